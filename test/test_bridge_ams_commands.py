# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
AMS services: car commands in the heartbeat, charger-role frames.

Through the one command pipeline without ROS (``bench_factory``, ``with_ams``: the bridge's
command side on a python-can virtual bus, the simulated AMS on the same bus); on a real node
(``rig_factory``, ``with_ams_node``) where ROS itself is under test: rclpy's parameter ranges,
telemetry flowing while a call waits in an executor thread, the rclpy log lines.
"""
import threading
import time

import can
from diagnostic_msgs.msg import DiagnosticArray
import pytest
from sensor_msgs.msg import BatteryState
from std_srvs.srv import Trigger

from ams_can_bridge.sim.ams import AmsSimulator
from ams_can_bridge.sim.runner import SimRunner
from command_bench import unique_channel
from helpers import assert_ended

BASE = 0x300
HEARTBEAT = BASE + 0x005


def ams_with_simulator(factory):
    """Yield a maker of (bridge, simulated AMS with 3 banks) on one virtual channel."""
    runners = []

    def make(precharge_time=0.3, sim_options=None, **params):
        channel = unique_channel('ams')
        sim = AmsSimulator(bank_count=3, precharge_time=precharge_time, **(sim_options or {}))
        runner = SimRunner(can.Bus(interface='virtual', channel=channel), [sim])
        runners.append(runner)
        runner.start()
        bridge = factory(ams_params(**params), channel=channel)
        device = bridge.devices['ams']
        assert bridge.wait(lambda: device.master_view().state == 1), 'no AMS IDLE'
        return bridge, sim
    yield make
    for runner in runners:
        runner.stop()
        runner.bus.shutdown()


@pytest.fixture
def with_ams(bench_factory):
    """Make the command side and a simulated AMS (3 banks) on one channel, commands on."""
    yield from ams_with_simulator(bench_factory)


@pytest.fixture
def with_ams_node(rig_factory):
    """Make a node and a simulated AMS (3 banks) on one channel, commands enabled."""
    yield from ams_with_simulator(rig_factory)


def ams_params(enabled=True, **extra):
    params = {'devices': ['ams'], 'commands_allowed': True, 'commands_enabled': enabled,
              'ams.bank_count': 3,
              'ams.heartbeat_period': 0.02, 'ams.command_timeout': 2.0}
    params.update(extra)
    return params


def commands_sent(rig, mark=0):
    """Frames other than the heartbeat, as (id, data)."""
    return [(f.arbitration_id, f.data) for _, f in rig.capture.since(mark)
            if f.arbitration_id != HEARTBEAT]


def heartbeat_commands(rig, mark=0):
    """Command nibble of every heartbeat since mark."""
    return [f.data[0] & 0x0F for _, f in rig.capture.since(mark, HEARTBEAT)]


# --- charger role: frames written by hand from doc/protocols.md section 1 ---------------------
CHARGER = BASE + 0x010


def charger_frames(rig, mark=0):
    """Return the data of every charger command (0x310) since mark."""
    return [f.data for _, f in rig.capture.since(mark, CHARGER)]


def test_start_charging_repeats_start_every_100_ms_until_stop_charging(bench_factory):
    bench = bench_factory(ams_params())
    mark = bench.capture.mark()
    first = bench.call('/ams/start_charging')
    assert first.success, first.message
    assert 'repeated every 100 ms until stop_charging' in first.message
    assert bench.wait(lambda: len(charger_frames(bench, mark)) >= 4)  # the first START + 3 repeats
    fourth = time.monotonic()
    again = bench.call('/ams/start_charging')
    assert again.success and 'already repeated' in again.message, again.message
    repeat = bench.devices['ams'].charger.thread
    # a tick is 1 ms: the bench answers within the ms of the repeat just seen (a ROS call
    # takes longer), and a STOP sent in that ms would rightly carry the same tick
    assert bench.wait(lambda: time.monotonic() - fourth > 0.002)
    second = bench.call('/ams/stop_charging')
    assert second.success, second.message
    assert 'the repeated START has ended' in second.message
    # stopped for good: the repeat's thread has ended, so no START can follow; a marker
    # after the call shows everything sent until then, the STOP last
    assert_ended(repeat, 'the charger repeat')
    bench.capture.sync()
    frames = charger_frames(bench, mark)
    # doc/protocols.md section 1: DLC 3, b0 bits 1..0 = 1 START / 2 STOP, b1..2 = tick (BE)
    assert all(len(d) == 3 for d in frames)
    assert [d[0] for d in frames] == [1] * (len(frames) - 1) + [2]  # STOP once, last
    assert len(frames) >= 5
    ticks = [d[1] << 8 | d[2] for d in frames]
    steps = [(b - a) & 0xFFFF for a, b in zip(ticks, ticks[1:])]
    assert all(0 < step < 2000 for step in steps), ticks  # ms, each frame its own tick
    values = bench.devices['ams'].diagnostic_report().values
    assert values['charger START repeated'].startswith('no')


def test_disarm_stops_the_repeated_start_at_once_and_rearming_does_not_resume_it(
        bench_factory):
    bench = bench_factory(ams_params())
    mark = bench.capture.mark()
    assert bench.call('/ams/start_charging').success
    assert bench.wait(lambda: len(charger_frames(bench, mark)) >= 3)
    charger = bench.devices['ams'].charger
    repeat = charger.thread
    assert bench.set_param('commands_enabled', False).successful
    frames_out = bench.frames_out()
    # at once: the repeat's thread has ended and, the heartbeat stopped too, nothing at all
    # was sent after set_param returned: no START, and no STOP while disarmed
    assert_ended(repeat, 'the charger repeat')
    bench.assert_silent_since(frames_out)
    disarmed = bench.capture.mark()
    assert bench.set_param('commands_enabled', True).successful
    # re-armed: the heartbeat is back, the repeat is not (no thread to send a START)
    assert not charger.active and charger.thread is None
    assert bench.wait(lambda: len(heartbeat_commands(bench, disarmed)) >= 3)
    bench.capture.sync()
    assert charger_frames(bench, disarmed) == []
    assert set(d[0] for d in charger_frames(bench, mark)) == {1}


def test_set_charge_current_and_override_bank_count(bench_factory):
    bench = bench_factory(ams_params(**{'ams.charge_current_a': 12.5}))
    mark = bench.capture.mark()
    assert bench.call('/ams/set_charge_current').success
    assert bench.call('/ams/override_bank_count').success
    assert bench.wait(lambda: len(commands_sent(bench, mark)) >= 2)
    assert commands_sent(bench, mark) == [(0x350, bytes([125])), (0x351, bytes([3]))]


def test_charge_current_unset_or_out_of_range_is_refused_and_nothing_sent(rig_factory):
    rig = rig_factory(ams_params())
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/ams/set_charge_current')
    assert not response.success
    assert 'ams.charge_current_a is not set' in response.message
    assert 'nothing was sent' in response.message
    for value in (25.6, -1.0, 0.15):
        result = rig.set_param('ams.charge_current_a', value)
        assert not result.successful and 'ams.charge_current_a' in result.reason
    assert not rig.set_param('ams.bank_count', 6).successful
    rig.capture.sync()  # a marker after the calls, no sleep
    assert commands_sent(rig, mark) == []


# --- car commands without an AMS on the bus --------------------------------------------
def test_state_command_times_out_when_no_ams_answers(bench_factory):
    bench = bench_factory(ams_params(**{'ams.command_timeout': 0.5}))
    mark = bench.capture.mark()
    t0 = time.monotonic()
    response = bench.call('/ams/enable_sc')
    assert time.monotonic() - t0 >= 0.5
    assert not response.success
    assert 'timeout after 0.5 s waiting for SC_ENABLED' in response.message
    assert 'not reported yet' in response.message
    bench.capture.sync()  # every heartbeat sent before the answer is captured by now
    commands = heartbeat_commands(bench, mark)
    assert 1 in commands  # ENABLE_SC was carried while waiting
    last = max(i for i, c in enumerate(commands) if c == 1)
    n = len(commands)
    assert bench.wait(lambda: len(heartbeat_commands(bench, mark)) >= n + 3)
    assert set(heartbeat_commands(bench, mark)[last + 1:]) == {0}  # back to NO_COMMAND


def test_one_shot_commands_answer_once_carried(bench_factory):
    bench = bench_factory(ams_params())
    mark = bench.capture.mark()
    for service, command in (('set_bank_count', 5), ('sync_time', 6)):
        response = bench.call(f'/ams/{service}')
        assert response.success, response.message
        assert 'sent in the heartbeat' in response.message
    assert bench.wait(lambda: len(heartbeat_commands(bench, mark)) >= 20)
    commands = heartbeat_commands(bench, mark)
    assert commands.count(5) == 1 and commands.count(6) == 1
    frames = bench.capture.since(mark, HEARTBEAT)
    assert all(f.data[0] >> 4 == 3 for _, f in frames)  # bank count from ams.bank_count


# --- car commands against the simulated AMS ----------------------------------------------
def test_full_sequence_sc_ts_drive_abort(with_ams):
    bench, sim = with_ams()
    for service, target in (('enable_sc', 'SC_ENABLED'), ('enable_ts', 'TS_ACTIVE'),
                            ('enable_drive', 'DRIVE'), ('abort', 'IDLE')):
        response = bench.call(f'/ams/{service}')
        assert response.success, response.message
        assert f'AMS reports {target}' in response.message
        assert sim.state.name == target
    # TS_ACTIVE came after PRECHARGING, as the AMS reported it on the bus
    states = [f.data[1] & 0x1F for _, f in bench.capture.since(0, BASE)]
    assert 7 in states and states.index(7) < states.index(3)


def test_enable_drive_from_idle_is_refused_at_once_naming_ts_active(with_ams):
    bench, sim = with_ams(**{'ams.command_timeout': 30.0})  # waiting it out would fail the call
    mark = bench.capture.mark()
    response = bench.call('/ams/enable_drive')
    assert not response.success
    assert 'ENABLE_DRIVE refused: the AMS is in IDLE' in response.message, response.message
    assert 'it must be TS_ACTIVE first (call enable_sc, then enable_ts)' in response.message
    assert 'nothing was sent' in response.message
    # nothing sent beyond the heartbeat, which runs on with NO_COMMAND
    n = len(heartbeat_commands(bench, mark))
    assert bench.wait(lambda: len(heartbeat_commands(bench, mark)) >= n + 5)
    assert set(heartbeat_commands(bench, mark)) == {0}
    bridge_ids = {BASE + 0x010, BASE + 0x050, BASE + 0x051}
    assert not [f for _, f in bench.capture.since(mark) if f.arbitration_id in bridge_ids]
    assert sim.state.name == 'IDLE'


def test_an_ams_watching_the_charger_keeps_charging_while_start_repeats(with_ams):
    # an AMS that leaves CHARGING 0.5 s after the last charger command (5 missed periods)
    bench, sim = with_ams(precharge_time=0.1, sim_options={'charger_timeout': 0.5})
    assert bench.call('/ams/start_charging').success
    assert bench.wait(lambda: sim.state.name == 'CHARGING')
    mark = bench.capture.mark()
    # 2 s of heartbeats (20 ms): four times the AMS's charger timeout, still CHARGING
    assert bench.wait(lambda: len(heartbeat_commands(bench, mark)) >= 100)
    assert sim.state.name == 'CHARGING'
    assert bench.call('/ams/stop_charging').success
    assert bench.wait(lambda: sim.state.name == 'IDLE')


def test_silent_ams_times_out(with_ams):
    bench, sim = with_ams(**{'ams.command_timeout': 0.5})
    sim.faults.silent = True
    response = bench.call('/ams/enable_sc')
    assert not response.success
    assert 'timeout after 0.5 s waiting for SC_ENABLED' in response.message
    assert 'AMS state: IDLE' in response.message  # the last state it reported


def test_ams_error_answers_failure_with_state_and_error_names(with_ams):
    bench, sim = with_ams(precharge_time=10.0)
    assert bench.call('/ams/enable_sc').success
    call = bench.call_in_thread('/ams/enable_ts')
    assert bench.wait(lambda: sim.state.name == 'PRECHARGING')
    sim.faults.error_code = 15  # PRE_TIMEOUT
    call['thread'].join(5)
    response = call['response']
    assert not response.success
    assert 'failed' in response.message and 'PRE_TIMEOUT' in response.message
    assert 'ERROR' in response.message


def test_abort_during_a_waiting_enable_ts(with_ams):
    bench, sim = with_ams(precharge_time=10.0, **{'ams.command_timeout': 5.0})
    assert bench.call('/ams/enable_sc').success
    mark = bench.capture.mark()
    call = bench.call_in_thread('/ams/enable_ts')
    assert bench.wait(lambda: sim.state.name == 'PRECHARGING')
    abort = bench.call('/ams/abort')
    call['thread'].join(5)
    assert abort.success and 'AMS reports IDLE' in abort.message, abort.message
    enable = call['response']
    assert not enable.success and 'aborted' in enable.message
    bench.capture.sync()  # every heartbeat sent before the answers is captured by now
    commands = heartbeat_commands(bench, mark)
    first_abort = commands.index(4)
    # ABORT replaced ENABLE_TS in the very next heartbeat: ...2, 2, 4... with no gap,
    # and no ENABLE_TS ever after it
    assert commands[first_abort - 1] == 2, commands
    assert 2 not in commands[first_abort:]
    assert sim.state.name == 'IDLE'
    n = len(commands)
    assert bench.wait(lambda: len(heartbeat_commands(bench, mark)) >= n + 3)
    assert heartbeat_commands(bench, mark)[-1] == 0  # ABORT ends once IDLE was reported


def test_telemetry_flows_while_a_command_waits(with_ams_node):
    rig, sim = with_ams_node(precharge_time=10.0, **{'ams.command_timeout': 1.5,
                                                     'diagnostics_period': 0.2})
    stamps = []
    diag_stamps = []
    lock = threading.Lock()
    hardware_id = f'virtual:{rig.channel}'

    def on_msg(msg):
        with lock:
            stamps.append(time.monotonic())

    def on_diag(msg):
        # other processes may publish /diagnostics too: count this node's arrays only
        if any(s.hardware_id == hardware_id for s in msg.status):
            with lock:
                diag_stamps.append(time.monotonic())
    rig.client.create_subscription(BatteryState, '/ams/battery_state', on_msg, 50)
    rig.client.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 50)
    assert rig.wait(lambda: len(stamps) >= 2 and len(diag_stamps) >= 1)
    assert rig.call(Trigger, '/ams/enable_sc').success
    t0 = time.monotonic()
    response = rig.call(Trigger, '/ams/enable_ts')  # waits in PRECHARGING until the timeout
    t1 = time.monotonic()
    # The call waited its whole timeout (the AMS simulator, in this process, goes to
    # PRECHARGING on the heartbeats; a machine that stalls the process for a second starves
    # them and it stays IDLE: a fact about the machine, not this test's point, which is what
    # arrives while a command waits).
    assert not response.success and 'timeout after 1.5 s' in response.message, response.message
    assert t1 - t0 >= 1.4, t1 - t0
    with lock:
        during = [t for t in stamps if t0 < t < t1]
        diag_during = [t for t in diag_stamps if t0 < t < t1]
    # the AMS status comes at 10 Hz: most of ~15 messages must arrive while the call waits
    assert len(during) >= 7, len(during)
    # diagnostics every 0.2 s: ~7 arrays in 1.5 s; at least 3 prove they did not pause
    assert len(diag_during) >= 3, len(diag_during)


def test_every_command_frame_and_answer_is_logged_the_heartbeat_only_starts_and_stops(
        rig_factory, capfd):
    """Issue 18.10: INFO per frame sent on a service call; the heartbeat: start and stop."""
    rig = rig_factory(ams_params(**{'ams.charge_current_a': 12.5,
                                    'ams.command_timeout': 0.3}))
    mark = rig.capture.mark()
    assert rig.call(Trigger, '/ams/set_charge_current').success
    assert not rig.call(Trigger, '/ams/enable_sc').success  # no AMS: times out
    rig.wait(lambda: len(rig.capture.since(mark, HEARTBEAT)) >= 10, what='heartbeats')
    assert rig.set_param('commands_enabled', False).successful
    refused = rig.call(Trigger, '/ams/start_charging')
    assert not refused.success
    err = capfd.readouterr().err  # the set and the calls are answered: all logged already
    lines = [line for line in err.splitlines() if '[ams_can_bridge]' in line]
    info = [line for line in lines if line.startswith('[INFO]')]
    assert any('ams: heartbeat started: car status 0x305 every 20 ms' in line
               for line in info), lines
    assert any('ams/set_charge_current: 350#7D sent' in line for line in info), lines
    assert any('ams/set_charge_current: answered success=True' in line for line in info)
    assert any(line.startswith('[WARN]') and 'ams/enable_sc: answered success=False' in line
               and 'ENABLE_SC' in line for line in lines), lines
    assert any('ams: heartbeat stopped (commands_enabled is false)' in line for line in info)
    assert any('ams/start_charging: answered success=False' in line
               and 'nothing was sent' in line for line in lines), lines
    # dozens of heartbeats went out, none of them logged one by one
    assert not [line for line in lines if '305#' in line], lines
