# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
launch/bridge.launch.py: commands_allowed given at launch applies only when given (issue 18.6).

``launch`` is not installed here (not on PyPI), so the launch file cannot be run: its node
parameters come from ``parameters.launch_parameters``, tested here and then handed to the
installed bridge as launch_ros hands them over (a params file, then the dict as values);
the launch file itself is read as source to check it uses that helper and its default.
"""
from __future__ import annotations

import ast
import os
from pathlib import Path
import signal
import subprocess
import threading

import pytest

from ams_can_bridge.parameters import launch_parameters
from executables import bridge_executable

LAUNCH = Path(__file__).resolve().parent.parent / 'launch' / 'bridge.launch.py'
ARMED = ('/**:\n  ros__parameters:\n    commands_allowed: true\n    commands_enabled: true\n'
         '    can: {interface: virtual, channel: launch_%d}\n')


def test_commands_allowed_joins_the_parameters_only_when_given():
    assert launch_parameters('pack.yaml') == ['pack.yaml']
    assert launch_parameters('pack.yaml', '') == ['pack.yaml']
    assert launch_parameters('pack.yaml', 'true') == ['pack.yaml', {'commands_allowed': True}]
    assert launch_parameters('pack.yaml', 'false') == ['pack.yaml', {'commands_allowed': False}]
    with pytest.raises(ValueError, match='use true or false, or leave it out'):
        launch_parameters('pack.yaml', 'maybe')
    assert launch_parameters('pack.yaml', '', 'false') == ['pack.yaml', {'autostart': False}]
    assert launch_parameters('pack.yaml', 'true', 'true') == [
        'pack.yaml', {'commands_allowed': True, 'autostart': True}]
    with pytest.raises(ValueError, match='autostart'):
        launch_parameters('pack.yaml', '', 'later')


def test_the_launch_file_uses_the_helper_and_defaults_to_not_given():
    tree = ast.parse(LAUNCH.read_text())
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)]
    names = {getattr(c.func, 'id', getattr(c.func, 'attr', '')) for c in calls}
    assert 'launch_parameters' in names and 'ParameterValue' not in names
    [argument] = [c for c in calls if getattr(c.func, 'id', '') == 'DeclareLaunchArgument'
                  and c.args and c.args[0].value == 'commands_allowed']
    keywords = {k.arg: k.value for k in argument.keywords}
    assert keywords['default_value'].value == ''
    assert [e.value for e in keywords['choices'].elts] == ['true', 'false', '']
    nodes = [c for c in calls if getattr(c.func, 'id', '') == 'action']
    assert len(nodes) == 1
    # autostart:=false: a launch_ros LifecycleNode for a lifecycle manager, else a Node
    [choice] = [n.value for n in ast.walk(tree) if isinstance(n, ast.Assign)
                and getattr(n.targets[0], 'id', '') == 'action']
    assert {choice.body.id, choice.orelse.id} == {'LifecycleNode', 'Node'}
    assert ast.unparse(choice.test).endswith("== 'false'") and choice.body.id == 'LifecycleNode'
    [argument] = [c for c in calls if getattr(c.func, 'id', '') == 'DeclareLaunchArgument'
                  and c.args and c.args[0].value == 'autostart']
    assert {k.arg: k.value for k in argument.keywords}['default_value'].value == ''
    [parameters] = [k.value for k in nodes[0].keywords if k.arg == 'parameters']
    assert getattr(parameters.func, 'id', '') == 'launch_parameters'


def test_without_a_params_file_the_launch_file_refuses_naming_it():
    """Issue 31: no silent ZEVA BMS16 bridge (the old default) when params_file is left out."""
    with pytest.raises(ValueError) as refused:
        launch_parameters('', examples='/opt/share/ams_can_bridge/config')
    assert str(refused.value) == (
        'params_file is required: ros2 launch ams_can_bridge bridge.launch.py '
        'params_file:=/path/to/your.yaml (copy the example for your devices from the '
        'config/*.yaml files in /opt/share/ams_can_bridge/config and set its can.* values)')
    tree = ast.parse(LAUNCH.read_text())
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)]
    [argument] = [c for c in calls if getattr(c.func, 'id', '') == 'DeclareLaunchArgument'
                  and c.args and c.args[0].value == 'params_file']
    assert {k.arg: k.value for k in argument.keywords}['default_value'].value == ''
    assert 'bms16.yaml' not in LAUNCH.read_text()
    [helper] = [c for c in calls if getattr(c.func, 'id', '') == 'launch_parameters']
    assert 'examples' in {k.arg for k in helper.keywords}


def command_line(parameters: list) -> list[str]:
    """Return the bridge's arguments for a launch Node's parameters (files, then values)."""
    args = [bridge_executable(), '--ros-args']
    for entry in parameters:
        if isinstance(entry, str):
            args += ['--params-file', entry]
        else:
            args += [a for k, v in entry.items() for a in ('-p', f'{k}:={str(v).lower()}')]
    return args


def test_launched_without_the_argument_the_params_file_arms(tmp_path):
    params = tmp_path / 'armed.yaml'
    params.write_text(ARMED % os.getpid())
    proc = subprocess.Popen(command_line(launch_parameters(str(params))),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=dict(os.environ))
    watchdog = threading.Timer(30.0, proc.kill)
    watchdog.start()
    lines = []
    try:
        for line in proc.stdout:
            lines.append(line)
            if 'commands ENABLED' in line:
                break
    finally:
        watchdog.cancel()
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=20)
    output = ''.join(lines) + rest
    assert 'commands ENABLED (commands_enabled set at launch)' in output, output
    assert proc.returncode == 0, output


def test_launched_with_commands_allowed_false_the_argument_wins(tmp_path):
    params = tmp_path / 'armed.yaml'
    params.write_text(ARMED % os.getpid())
    proc = subprocess.run(command_line(launch_parameters(str(params), 'false')),
                          capture_output=True, text=True, timeout=30, env=dict(os.environ))
    assert proc.returncode == 2
    assert 'commands_enabled = true refused: commands_allowed is false' in proc.stderr
