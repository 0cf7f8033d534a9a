"""
Launch the ams_can_bridge bridge node with a parameter file.

    ros2 launch ams_can_bridge bridge.launch.py params_file:=/path/to/my_pack.yaml
    ros2 launch ams_can_bridge bridge.launch.py params_file:=... commands_allowed:=true

params_file defaults to the installed config/bms16.yaml; namespace (default empty) puts
the node and its relative topics (<device>/battery_state, ...) under a namespace.
commands_allowed (default false) is the launch-only first key of the transmit gate: only
with it true can commands_enabled (the second key, in the params file or set at run time
by the supervisor) become true. Given here, it overrides the params file.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    """Declare params_file / namespace / commands_allowed and start the bridge node."""
    default_params = os.path.join(
        get_package_share_directory('ams_can_bridge'), 'config', 'bms16.yaml')
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file', default_value=default_params,
            description='YAML parameter file of the bridge (see config/*.yaml)'),
        DeclareLaunchArgument(
            'namespace', default_value='',
            description='namespace of the node and its topics'),
        DeclareLaunchArgument(
            'commands_allowed', default_value='false', choices=['true', 'false'],
            description='first key of the transmit gate (launch only): true lets '
                        'commands_enabled become true'),
        Node(
            package='ams_can_bridge',
            executable='bridge',
            name='ams_can_bridge',
            namespace=LaunchConfiguration('namespace'),
            parameters=[
                LaunchConfiguration('params_file'),
                {'commands_allowed': ParameterValue(
                    LaunchConfiguration('commands_allowed'), value_type=bool)},
            ],
            output='screen',
            emulate_tty=True,
        ),
    ])
