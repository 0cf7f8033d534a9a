# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Launch the ams_can_bridge bridge node with a parameter file.

    ros2 launch ams_can_bridge bridge.launch.py params_file:=/path/to/my_pack.yaml
    ros2 launch ams_can_bridge bridge.launch.py params_file:=... commands_allowed:=true

params_file is required (the examples are the installed config/*.yaml: copy yours and set
its can.* values); namespace (default empty) puts the node and its relative topics
(<device>/battery_state, ...) under a namespace.
commands_allowed is the launch-only first key of the transmit gate: only with it true can
commands_enabled (the second key, in the params file or set at run time by the supervisor)
become true. Given here (true or false), it replaces the params file's value; left out, the
params file's value holds (false when the file does not set it).

The bridge is a lifecycle node that configures and activates itself (autostart, the default).
autostart:=false starts it as a launch_ros LifecycleNode that waits, unconfigured, for a
lifecycle manager (or ``ros2 lifecycle set /ams_can_bridge configure`` / ``activate``).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node

from ams_can_bridge.parameters import launch_parameters


def _bridge(context):
    """Start the node; commands_allowed / autostart join its parameters only when given."""
    autostart = LaunchConfiguration('autostart').perform(context)
    action = LifecycleNode if autostart.strip().lower() == 'false' else Node
    return [action(
        package='ams_can_bridge',
        executable='bridge',
        name='ams_can_bridge',
        namespace=LaunchConfiguration('namespace'),
        parameters=launch_parameters(
            LaunchConfiguration('params_file').perform(context),
            LaunchConfiguration('commands_allowed').perform(context), autostart,
            examples=os.path.join(get_package_share_directory('ams_can_bridge'), 'config')),
        output='screen',
        emulate_tty=True,
    )]


def generate_launch_description():
    """Declare params_file / namespace / commands_allowed and start the bridge node."""
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file', default_value='',
            description='YAML parameter file of the bridge, required (examples: the installed '
                        'config/*.yaml)'),
        DeclareLaunchArgument(
            'namespace', default_value='',
            description='namespace of the node and its topics'),
        DeclareLaunchArgument(
            'commands_allowed', default_value='', choices=['true', 'false', ''],
            description='first key of the transmit gate (launch only): true lets '
                        'commands_enabled become true; left out, the params file decides'),
        DeclareLaunchArgument(
            'autostart', default_value='', choices=['true', 'false', ''],
            description='lifecycle: false starts it unconfigured for a lifecycle manager; '
                        'left out, the params file decides (default true: active by itself)'),
        OpaqueFunction(function=_bridge),
    ])
