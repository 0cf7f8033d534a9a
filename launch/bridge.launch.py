"""
Launch the ams_can_bridge bridge node with a parameter file.

    ros2 launch ams_can_bridge bridge.launch.py params_file:=/path/to/my_pack.yaml

params_file defaults to the installed config/bms16.yaml; namespace (default empty) puts
the node and its relative topics (<device>/battery_state, ...) under a namespace.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    """Declare params_file / namespace and start the bridge node with them."""
    default_params = os.path.join(
        get_package_share_directory('ams_can_bridge'), 'config', 'bms16.yaml')
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file', default_value=default_params,
            description='YAML parameter file of the bridge (see config/*.yaml)'),
        DeclareLaunchArgument(
            'namespace', default_value='',
            description='namespace of the node and its topics'),
        Node(
            package='ams_can_bridge',
            executable='bridge',
            name='ams_can_bridge',
            namespace=LaunchConfiguration('namespace'),
            parameters=[LaunchConfiguration('params_file')],
            output='screen',
            emulate_tty=True,
        ),
    ])
