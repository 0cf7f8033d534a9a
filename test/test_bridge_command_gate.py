# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The transmit gate and the AMS heartbeat on a real (virtual) bus.

On a real node where the parameters, the services and their answers are under test; the
heartbeat's period, counter and run-time gate through the command side without ROS
(``bench_factory``).
"""
import os
import statistics
import subprocess
import sys

import pytest
from std_srvs.srv import SetBool, Trigger

from helpers import assert_ended


AMS_SERVICES = ('enable_sc', 'enable_ts', 'enable_drive', 'abort', 'set_bank_count',
                'sync_time', 'start_charging', 'stop_charging', 'set_charge_current',
                'override_bank_count')
BMS16_SERVICES = ('write_config', 'acknowledge_error', 'reset_soc', 'power_off')
EVMS3_SERVICES = ('write_config', 'acknowledge_error', 'reset_soc')
HEARTBEAT_ID = 0x305


def all_devices(enabled=False, **extra):
    params = {'devices': ['ams', 'ivt_s', 'evms3', 'bms16'], 'commands_allowed': True,
              'commands_enabled': enabled,
              'ams.charge_current_a': 10.0}
    params.update(extra)
    return params


def assert_no_periodic_sender(bridge):
    """Assert that the AMS heartbeat and charger repeat of a Rig or Bench have no thread."""
    ams = bridge.devices['ams']
    assert not ams.master.running and ams.master.thread is None
    assert not ams.charger.active and ams.charger.thread is None


def test_disabled_bridge_sends_nothing_and_refuses_every_service(rig_factory):
    rig = rig_factory(all_devices())
    calls = [(Trigger, f'/ams/{s}', {}) for s in AMS_SERVICES]
    calls += [(Trigger, f'/bms16/{s}', {}) for s in BMS16_SERVICES]
    calls += [(Trigger, f'/evms3/{s}', {}) for s in EVMS3_SERVICES]
    calls += [(SetBool, '/evms3/set_setup_mode', {'data': True}),
              (SetBool, '/evms3/set_setup_mode', {'data': False})]
    for srv_type, name, fields in calls:
        response = rig.call(srv_type, name, **fields)
        assert not response.success, name
        assert 'commands_enabled' in response.message, (name, response.message)
        assert 'nothing was sent' in response.message
    # a marker after the calls: every frame they sent is captured by then, and none was
    rig.assert_silent_since(0)
    # The senders with threads of their own, which a marker after the calls cannot show
    # silent, never started: no heartbeat thread, no repeated charger START.
    assert_no_periodic_sender(rig)


def test_heartbeat_period_and_counter_and_run_time_gate(bench_factory):
    bench = bench_factory({'devices': ['ams'], 'ams.heartbeat_period': 0.01,
                           'ams.bank_count': 3, 'commands_allowed': True})
    assert_no_periodic_sender(bench)  # allowed, not enabled: no heartbeat
    bench.assert_silent_since(0)
    assert bench.set_param('commands_enabled', True).successful
    assert bench.wait(lambda: len(bench.capture.since(0, HEARTBEAT_ID)) >= 300, timeout=20)
    frames = bench.capture.since(0, HEARTBEAT_ID)
    counters = [f.data[1] for _, f in frames]
    assert all((b - a) & 0xFF == 1 for a, b in zip(counters, counters[1:])), counters
    assert any(a == 255 and b == 0 for a, b in zip(counters, counters[1:]))  # wrapped
    assert all(f.data[0] == 0x30 and len(f.data) == 2 for _, f in frames)  # 3 banks, no cmd
    times = [t for t, _ in frames]
    # the 10 ms parameter is in use, not the 50 ms default; the absolute schedule never
    # sends more than one frame per slot (a late thread skips slots, it does not burst).
    # How close the period holds is a figure for bench/bench_heartbeat.py, not a test.
    assert statistics.median(b - a for a, b in zip(times, times[1:])) < 0.05 / 2
    assert len(times) - 1 <= (times[-1] - times[0]) / 0.01 + 2
    heartbeat = bench.devices['ams'].master.thread
    assert bench.set_param('commands_enabled', False).successful
    frames_out = bench.frames_out()  # a frame in flight is on the bus when set_param returns
    assert_ended(heartbeat, 'the heartbeat')
    bench.assert_silent_since(frames_out)  # nothing after the switch returned
    mark = bench.capture.mark()
    last_sent = bench.capture.since(0, HEARTBEAT_ID)[-1][1].data[1]
    # on again: heartbeats again, the counter continues exactly where it stopped
    assert bench.set_param('commands_enabled', True).successful
    assert bench.wait(lambda: len(bench.capture.since(mark)) >= 3)
    again = [f.data[1] for _, f in bench.capture.since(mark, HEARTBEAT_ID)]
    assert again[:3] == [(last_sent + k) & 0xFF for k in (1, 2, 3)], (last_sent, again)


def test_period_and_bank_count_follow_parameters(rig_factory):
    rig = rig_factory({'devices': ['ams'], 'commands_allowed': True, 'commands_enabled': True,
                       'ams.heartbeat_period': 0.2})
    assert rig.wait(lambda: len(rig.capture.since(0)) >= 1)
    assert rig.set_param('ams.heartbeat_period', 0.01).successful
    assert rig.set_param('ams.bank_count', 5).successful
    mark = rig.capture.mark()
    assert rig.wait(lambda: len(rig.capture.since(mark)) >= 50, timeout=10)
    times = [t for t, _ in rig.capture.since(mark)]
    assert statistics.median(b - a for a, b in zip(times, times[1:])) < 0.2 / 2  # new period
    assert rig.capture.since(mark)[-1][1].data[0] == 0x50
    result = rig.set_param('ams.heartbeat_period', 0.001)
    assert not result.successful and 'ams.heartbeat_period' in result.reason


def test_invalid_config_value_in_a_params_file_stops_the_node(tmp_path):
    params = tmp_path / 'bad.yaml'
    params.write_text(
        'ams_can_bridge:\n'
        '  ros__parameters:\n'
        '    can.interface: virtual\n'
        '    can.channel: bad-config\n'
        '    devices: [bms16]\n'
        '    bms16.config.shunt_size_a: 250\n')
    proc = subprocess.run(
        [sys.executable, '-m', 'ams_can_bridge.ros.bridge_main', '--ros-args',
         '--params-file', str(params)],
        capture_output=True, text=True, timeout=60, env=dict(os.environ))
    assert proc.returncode != 0
    output = proc.stdout + proc.stderr
    assert 'bms16.config.shunt_size_a' in output and '250' in output, output
    assert '100, 200 or 500' in output, output


def test_commands_enabled_needs_commands_allowed_at_run_time(rig_factory, capfd):
    rig = rig_factory({'devices': ['ams', 'bms16'], 'ams.heartbeat_period': 0.01})
    result = rig.set_param('commands_enabled', True)
    assert not result.successful
    assert 'commands_allowed is false' in result.reason and 'launch' in result.reason
    assert rig.node.commands_enabled is False
    assert rig.node.get_parameter('commands_enabled').value is False
    # the first key cannot be turned at run time: it is read-only
    assert not rig.set_param('commands_allowed', True).successful
    assert rig.node.commands_allowed is False
    response = rig.call(Trigger, '/bms16/reset_soc')
    assert not response.success and 'commands_allowed' in response.message
    rig.capture.sync()  # a marker after the calls, no sleep
    assert rig.capture.since(0) == []  # no heartbeat, no command
    assert 'refused: commands_enabled = true refused' in capfd.readouterr().err


def test_commands_enabled_at_launch_without_commands_allowed_stops_the_bridge():
    from rclpy.parameter import Parameter

    from ams_can_bridge.ros.bridge_node import BridgeNode, ConfigError
    from helpers import ros_context
    with ros_context() as context:
        with pytest.raises(ConfigError) as error:
            BridgeNode(context=context, parameter_overrides=[
                Parameter('can.interface', value='virtual'),
                Parameter('can.channel', value=f'gate-launch-{os.getpid()}'),
                Parameter('devices', value=['ams']),
                Parameter('commands_enabled', value=True)])
    assert 'commands_allowed is false' in str(error.value)


def test_every_change_of_commands_enabled_is_logged_and_counted(rig_factory, capfd):
    rig = rig_factory({'devices': ['bms16'], 'commands_allowed': True})
    assert rig.set_param('commands_enabled', True).successful
    assert rig.set_param('commands_enabled', True).successful  # no change: nothing logged
    assert rig.set_param('commands_enabled', False).successful
    err = capfd.readouterr().err
    assert err.count('commands_enabled false -> true') == 1, err
    assert err.count('commands_enabled true -> false') == 1, err
    assert 'the caller is not known to the node' in err
    values = rig.node.engine.bus_report().values
    assert values['commands_enabled changes'] == '2'
    assert values['commands_allowed'] == 'true' and values['commands_enabled'] == 'false'


def test_a_bug_in_a_command_is_an_internal_error_logged_with_its_traceback(rig_factory, capfd):
    # issue 21 step 7: a TypeError/ValueError from a device is a bug, not a refusal: it is
    # not answered as "cannot reset the SoC", but as an internal error, traceback in the log
    rig = rig_factory({'devices': ['bms16'], 'commands_allowed': True,
                       'commands_enabled': True})

    def broken():
        raise TypeError('unsupported operand')
    rig.node.devices['bms16'].reset_soc_frame = broken
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/bms16/reset_soc')
    assert not response.success
    assert response.message == ('bms16/reset_soc: internal error: TypeError: unsupported '
                                'operand; see the log'), response.message
    assert 'cannot' not in response.message
    rig.capture.sync()
    assert rig.capture.since(mark) == []
    err = capfd.readouterr().err
    assert 'bms16/reset_soc: internal error:' in err and 'Traceback' in err, err
    assert "raise TypeError('unsupported operand')" in err
    # the bridge goes on: the next call is served normally
    del rig.node.devices['bms16'].reset_soc_frame
    assert rig.call(Trigger, '/bms16/reset_soc').success
