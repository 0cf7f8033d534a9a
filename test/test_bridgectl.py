# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
bridgectl against real bridges: every subcommand, every exit code, --node and --namespace.

Two bridges on python-can virtual buses (command_rig): ``/ams_can_bridge`` with a simulated
AMS and IVT-S, commands allowed, and ``/car2/ams_can_bridge`` started without
commands_allowed. bridgectl runs as the user runs it: ``main(argv)`` in this process (its
own rclpy context, like a separate process) and, for the exit code seen by a shell, the
installed console script.
"""
from pathlib import Path
import subprocess
import sys

import can
import pytest

from ams_can_bridge.ros import bridgectl
from ams_can_bridge.sim.ams import AmsSimulator
from ams_can_bridge.sim.ivt_s import IvtSSimulator
from ams_can_bridge.sim.runner import SimRunner
from command_bench import unique_channel
from doc_blocks import block_after, commands, section
from executables import package_executable

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[1]
T = '--timeout'
WAIT = '20'  # s: generous on a loaded machine; a run that works answers in about a second


@pytest.fixture(scope='module')
def bridges():
    """Yield (armed-capable bridge with simulated AMS + IVT-S, bridge in car2 without)."""
    from command_rig import rigs
    channel = unique_channel('ctl')
    runner = SimRunner(can.Bus(interface='virtual', channel=channel),
                       [AmsSimulator(bank_count=3, precharge_time=0.2), IvtSSimulator()])
    runner.start()
    try:
        with rigs() as make:
            main = make({'devices': ['ams', 'ivt_s'], 'commands_allowed': True,
                         'ams.bank_count': 3, 'ams.heartbeat_period': 0.02,
                         'ams.command_timeout': 3.0}, channel=channel)
            car2 = make({'devices': ['ams']}, namespace='car2')
            assert main.wait(lambda: main.devices['ams'].master_view().state == 1), \
                'the simulated AMS never reported IDLE'
            yield main, car2
    finally:
        runner.stop()
        runner.bus.shutdown()


def ctl(capsys, *argv):
    """Run bridgectl in this process; return (exit code, stdout, stderr)."""
    code = bridgectl.main([T, WAIT, *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_the_node_name_is_the_bridges():
    from ams_can_bridge.ros.bridge_node import NODE_NAME
    assert bridgectl.BRIDGE_NODE == NODE_NAME


@pytest.mark.parametrize('node, arm', [
    ('/ams_can_bridge', 'bridgectl arm, or ros2 param set /ams_can_bridge commands_enabled'),
    ('/car1/ams_can_bridge', 'bridgectl --namespace car1 arm, or ros2 param set /car1/'),
    ('/a/b/can1', 'bridgectl --namespace a/b --node can1 arm, or ros2 param set /a/b/can1 '),
])
def test_a_disarmed_bridge_says_how_to_arm_it_with_bridgectl(node, arm):
    import logging
    from ams_can_bridge.engine.gate import CommandGate
    gate = CommandGate('virtual:x', allowed=True, connect_wait=0.0,
                       logger=logging.getLogger('test'), node_name=node)
    assert arm in gate.refusal('enable the SC')


def test_bridgectl_is_in_the_readmes_ten_steps_and_on_the_executables_page():
    import importlib.util
    readme = (ROOT / 'README.md').read_text()
    step10 = readme.split('\n10. ', 1)[1].split('\n## ', 1)[0]
    assert '`bridgectl arm`' in step10 and '`bridgectl call ams/enable_sc`' in step10
    spec = importlib.util.spec_from_file_location('docgen', ROOT / 'doc' / 'docgen.py')
    docgen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(docgen)
    assert ('bridgectl', 'ams_can_bridge.ros.bridgectl:main') in docgen.console_scripts(ROOT)
    assert '{generated} executables' in (ROOT / 'doc' / 'executables.md').read_text()


@pytest.mark.process
def test_help_and_usage_errors_need_no_ros():
    code = ('import sys; from ams_can_bridge.ros.bridgectl import main; '
            'codes = [main(["--help"]), main(["call"]), main(["set", "x"]), '
            'main(["--timeout", "0", "list"]), main(["call", "ams/enable_sc", "maybe"])]; '
            'print(codes, "rclpy" in sys.modules)')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=60)
    assert done.stdout.strip().splitlines()[-1] == '[0, 2, 2, 2, 2] False', done
    assert 'usage: bridgectl' in done.stdout and 'arm' in done.stdout
    assert '--timeout must be > 0' in done.stderr


@pytest.mark.process
def test_no_bridge_exits_2_naming_the_node_and_the_domain():
    import os
    done = subprocess.run([package_executable('bridgectl'), '--namespace', 'nobody_here',
                           T, '2', 'get', 'commands_enabled'],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done
    assert 'no node /nobody_here/ams_can_bridge' in done.stderr
    assert f'ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}' in done.stderr


def test_arm_call_disarm(bridges, capsys):
    main, _ = bridges
    assert ctl(capsys, 'disarm')[0] == 0
    code, out, err = ctl(capsys, 'call', 'ams/enable_sc')
    assert code == 1 and 'success: false' in out and 'commands_enabled' in out
    code, out, _ = ctl(capsys, 'arm')
    assert (code, out) == (0, 'commands_enabled: true\n')
    assert main.node.get_parameter('commands_enabled').value is True
    code, out, _ = ctl(capsys, 'get', 'commands_enabled')
    assert (code, out) == (0, 'true\n')
    code, out, err = ctl(capsys, 'call', 'ams/enable_sc')
    assert code == 0, (out, err)
    assert out.startswith('success: true\nmessage: ') and 'SC_ENABLED' in out
    code, out, _ = ctl(capsys, 'call', '/ams/abort')  # an absolute name works as well
    assert code == 0 and 'success: true' in out
    assert ctl(capsys, 'disarm')[:2] == (0, 'commands_enabled: false\n')
    assert main.node.get_parameter('commands_enabled').value is False


def test_setbool_services_take_true_or_false(bridges, capsys):
    main, _ = bridges
    code, _, err = ctl(capsys, 'call', 'ivt_s/set_running')
    assert code == 2 and 'std_srvs/SetBool service: add true or false' in err
    code, _, err = ctl(capsys, 'call', 'ams/abort', 'true')
    assert code == 2 and 'Trigger service: it takes no true/false' in err
    assert ctl(capsys, 'arm')[0] == 0
    try:
        code, out, err = ctl(capsys, 'call', 'ivt_s/set_running', 'false')
        assert code == 0 and 'STOP' in out, (out, err)
        code, out, err = ctl(capsys, 'call', 'ivt_s/set_running', 'true')
        assert code == 0 and 'success: true' in out, (out, err)
    finally:
        ctl(capsys, 'disarm')


def test_unknown_service_is_a_usage_error_with_the_nearest_name(bridges, capsys):
    code, _, err = ctl(capsys, 'call', 'ams/enable_scc')
    assert code == 2 and 'Did you mean /ams/enable_sc' in err
    code, _, err = ctl(capsys, 'call', 'ams_can_bridge/ams/enable_sc')
    assert code == 2 and "follow the bridge's namespace, not its node name" in err


def test_get_and_set_parameters(bridges, capsys):
    main, _ = bridges
    code, out, err = ctl(capsys, 'set', 'ams.bank_count', '9')
    assert code == 1 and 'refused ams.bank_count = 9' in err
    assert main.node.get_parameter('ams.bank_count').value == 3
    assert ctl(capsys, 'set', 'ams.bank_count', '4')[:2] == (0, 'ams.bank_count: 4\n')
    assert main.node.get_parameter('ams.bank_count').value == 4
    # a float parameter takes an integer as written in YAML
    assert ctl(capsys, 'set', 'ams.command_timeout', '3')[:2] == (0,
                                                                  'ams.command_timeout: 3.0\n')
    assert ctl(capsys, 'get', 'ams.command_timeout')[:2] == (0, '3.0\n')
    code, _, err = ctl(capsys, 'get', 'ams.bank_cont')
    assert code == 1 and 'Did you mean ams.bank_count?' in err
    code, _, err = ctl(capsys, 'set', 'ams.bank_cont', '3')
    assert code == 1 and 'no parameter' in err
    ctl(capsys, 'set', 'ams.bank_count', '3')


def test_list_shows_services_under_the_namespace_and_parameters_on_the_node(bridges, capsys):
    code, out, _ = ctl(capsys, 'list')
    assert code == 0
    services, params = out.split('parameters of the node /ams_can_bridge')
    assert 'under its namespace / (not under the node name)' in services
    assert '  ams/enable_sc ' in services and 'std_srvs/srv/Trigger' in services
    assert '  ivt_s/set_running ' in services and 'std_srvs/srv/SetBool' in services
    assert 'get_parameters' not in services and 'change_state' not in services
    assert '  commands_allowed = true\n' in params and '  ams.bank_count = 3\n' in params
    assert '  ams.charge_current_a = (not set)\n' in params  # no default: shown unset


def test_namespace_and_node_select_the_bridge(bridges, capsys):
    _, car2 = bridges
    code, out, _ = ctl(capsys, '--namespace', 'car2', 'list')
    assert code == 0 and 'under its namespace /car2' in out
    assert '  commands_allowed = false\n' in out
    code, _, err = ctl(capsys, '--namespace', '/car2/', 'arm')  # slashes as ros2 writes it
    assert code == 1 and 'commands_allowed' in err
    assert car2.node.get_parameter('commands_enabled').value is False
    code, _, err = ctl(capsys, T, '2', '--node', 'other_bridge', 'list')
    assert code == 2 and 'no node /other_bridge' in err


def doc_commands(page, heading=None):
    """Return the bridgectl commands of the first bash block of a page (or of a section)."""
    text = section(page, heading) if heading else (ROOT / 'doc' / f'{page}.md').read_text()
    return [argv for argv in commands(block_after(text, '', 'bash')) if argv[0] == 'bridgectl']


@pytest.mark.parametrize('page, heading', [('commanding', 'Arming and calling with bridgectl'),
                                           ('ivt_s', None)])
def test_the_documented_bridgectl_steps_work(bridges, capsys, page, heading):
    steps = doc_commands(page, heading)
    assert len(steps) >= 4 and ['bridgectl', 'arm'] in steps
    try:
        for argv in steps:
            code, out, err = ctl(capsys, *argv[1:])
            assert code == 0, (argv, out, err)
    finally:
        ctl(capsys, 'disarm')
