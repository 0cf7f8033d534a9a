# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Commands under races and bus faults on a real (virtual) bus.

Through the one command pipeline without ROS (``bench_factory``: concurrent calls from
threads), and on a real node where ROS is part of the race: two clients, parameter sets
racing a write, the executor's threads held by calls that wait for the bus.

Defined behaviour (doc/commanding.md): one AMS command at a time, from
any number of clients: a second ``enable_*`` while one waits is refused; ``abort`` is never
refused and replaces the waiting command in the very next heartbeat. The frames of one
ZEVA call are never interleaved with another call's, and are built from one consistent
set of configuration values. A bus that goes down fails the waiting command with the
reason; nothing stale is sent when it returns.
"""
from __future__ import annotations

import sys
import threading
import time

import can
import pytest
from std_srvs.srv import Trigger

from ams_can_bridge.protocols import evms3 as evms3_proto
from helpers import assert_ended
from shared import bms16_params, EVMS3_CONFIG, evms3_in, evms3_params

HEARTBEAT = 0x305
ENABLE_TS, ENABLE_DRIVE, ABORT = 2, 3, 4
CAN_ERR_BUSOFF = 0x40


def ams(**extra):
    params = {'devices': ['ams'], 'commands_allowed': True, 'commands_enabled': True,
              'ams.heartbeat_period': 0.02, 'ams.command_timeout': 5.0,
              'can.reconnect_period': 0.3}
    params.update(extra)
    return params


def heartbeats(rig, mark=0):
    """(monotonic time, command nibble, counter) of every heartbeat since mark."""
    return [(t, f.data[0] & 0x0F, f.data[1]) for t, f in rig.capture.since(mark, HEARTBEAT)]


def wait_carried(rig, command, mark=0):
    assert rig.wait(lambda: any(c == command for _, c, _ in heartbeats(rig, mark)))


def test_bus_off_during_a_waiting_enable_ts_and_an_active_heartbeat(bench_factory):
    bench = bench_factory(ams())
    call = bench.call_in_thread('/ams/enable_ts')
    wait_carried(bench, ENABLE_TS)
    # the controller reports bus-off: the bridge closes the bus and reopens it alone
    bench.capture.bus.send(can.Message(arbitration_id=CAN_ERR_BUSOFF, is_error_frame=True,
                                       data=bytes(8)))
    call['thread'].join(5)
    response = call['response']
    assert not response.success
    assert 'not connected (bus-off' in response.message, response.message
    assert 'will not be sent later' in response.message
    bench.capture.sync()  # every heartbeat sent before the bus went down is captured now
    mark_down = bench.capture.mark()
    before = heartbeats(bench)
    assert bench.wait(
        lambda: bench.io.status().reconnects >= 1 and len(heartbeats(bench, mark_down)) >= 5)
    after = heartbeats(bench, mark_down)
    # no stale ENABLE_TS when the bus returns; the counter goes on from the last frame sent
    assert {c for _, c, _ in after} == {0}, after
    counters = [n for _, _, n in before + after]
    assert all((b - a) & 0xFF == 1 for a, b in zip(counters, counters[1:])), counters


@pytest.mark.parametrize('service, command', [('enable_ts', ENABLE_TS),
                                              ('enable_drive', ENABLE_DRIVE)])
def test_abort_during_a_waiting_enable(bench_factory, service, command):
    bench = bench_factory(ams(**{'ams.command_timeout': 1.0}))  # no AMS answers anything
    call = bench.call_in_thread(f'/ams/{service}')
    wait_carried(bench, command)
    abort = bench.call('/ams/abort')
    call['thread'].join(5)
    assert not call['response'].success and 'aborted' in call['response'].message
    assert not abort.success and 'waiting for IDLE' in abort.message  # nobody says IDLE
    bench.capture.sync()  # every heartbeat sent before the answers is captured now
    sent = [c for _, c, _ in heartbeats(bench)]
    first_abort = sent.index(ABORT)
    assert sent[first_abort - 1] == command  # replaced in the very next heartbeat
    assert command not in sent[first_abort:]
    n = len(sent)
    assert bench.wait(lambda: len(heartbeats(bench)) >= n + 3)
    assert command not in [c for _, c, _ in heartbeats(bench)][first_abort:]


def test_commands_disabled_during_a_waiting_call(bench_factory):
    bench = bench_factory(ams())
    call = bench.call_in_thread('/ams/enable_ts')
    wait_carried(bench, ENABLE_TS)
    heartbeat = bench.devices['ams'].master.thread
    assert bench.set_param('commands_enabled', False).successful
    frames_out = bench.frames_out()
    call['thread'].join(2)  # at once, not after ams.command_timeout (5 s)
    assert 'response' in call, 'the waiting call did not answer when commands were disabled'
    assert not call['response'].success
    assert 'commands_enabled was set to false' in call['response'].message
    # the heartbeat stopped with the switch: its thread has ended, and no frame was sent
    # after set_param returned (a marker after it is captured with nothing before it)
    assert_ended(heartbeat, 'the heartbeat')
    bench.assert_silent_since(frames_out)


def test_commands_disabled_while_waiting_for_the_bus(bench_factory, tmp_path):
    missing = tmp_path / 'ttyACM_never'
    bench = bench_factory({'devices': ['bms16'], 'commands_allowed': True,
                           'commands_enabled': True, 'can.interface': 'slcan',
                           'can.channel': str(missing), 'can.connect_wait': 30.0},
                          wait_connected=False)
    call = bench.call_in_thread('/bms16/reset_soc')
    # the call is waiting for the bus once it holds one of the gate's bus-wait slots
    assert bench.wait(lambda: bench.gate.bus_waiters() > 0)
    assert bench.set_param('commands_enabled', False).successful
    call['thread'].join(3)
    assert 'response' in call, 'the call kept waiting for the bus after the switch'
    assert 'commands_enabled was set to false while waiting' in call['response'].message


def test_two_clients_with_conflicting_commands(rig_factory):
    rig = rig_factory(ams(**{'ams.command_timeout': 1.0}))
    other = rig.other_client('second_supervisor')
    first = rig.call_in_thread(Trigger, '/ams/enable_ts')
    wait_carried(rig, ENABLE_TS)
    # the other client's command while the first waits: refused, nothing carried
    second = rig.call(Trigger, '/ams/enable_drive', client=other)
    assert not second.success
    assert 'ENABLE_TS is still in progress' in second.message, second.message
    # the other client's abort is never refused: it wins over the first client's command
    rig.call(Trigger, '/ams/abort', client=other)
    first['thread'].join(5)
    assert not first['response'].success and 'aborted' in first['response'].message
    assert ENABLE_DRIVE not in [c for _, c, _ in heartbeats(rig)]


def test_concurrent_zeva_calls_never_interleave_their_frames(bench_factory):
    bench = bench_factory(bms16_params())
    calls = []
    for _ in range(10):  # a second user's call while a write is on its way
        writer = bench.call_in_thread('/bms16/write_config')
        bench.call('/bms16/reset_soc')
        calls.append(writer)
    for writer in calls:
        writer['thread'].join(5)
        assert writer['response'].success, writer['response'].message
    assert bench.wait(lambda: len(bench.capture.since(0)) >= 30)
    ids = [f.arbitration_id for _, f in bench.capture.since(0)]
    assert ids.count(504) == ids.count(505) == ids.count(507) == 10
    assert all(ids[i + 1] == 505 for i, can_id in enumerate(ids) if can_id == 504), ids


def test_config_changes_during_write_config_send_one_consistent_set(rig_factory):
    other = dict(EVMS3_CONFIG, pack_capacity_ah=200, tacho_ppr=4, bms_hysteresis_v=0.1,
                 mpi_function=2, cells_per_module=[8] * 4 + [0] * 12)
    codec = evms3_proto.Evms3Codec(30, bms12_modules=0)

    def frames(config):
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in config.items()}
        cells = values.pop('cells_per_module')
        return [bytes(f.data) for f in [codec.encode(evms3_proto.BmsCellNumbers(cells))]
                + codec.config_frames(evms3_proto.Evms3Settings.from_mapping(values))]
    sets = {tuple(frames(EVMS3_CONFIG)): 'A', tuple(frames(other)): 'B'}
    assert len(sets) == 2
    rig = rig_factory(evms3_params())
    evms3_in(rig, 0)  # IDLE: configuration may be written
    stop = threading.Event()
    from rclpy.parameter import Parameter

    def flip():
        configs = [other, EVMS3_CONFIG]
        k = 0
        while not stop.is_set():
            rig.node.set_parameters_atomically([
                Parameter(f'evms3.config.{key}', value=value)
                for key, value in configs[k % 2].items()])
            k += 1
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as possible: provoke the race
    flipper = threading.Thread(target=flip, daemon=True)
    flipper.start()
    try:
        for _ in range(15):
            response = rig.call(Trigger, '/evms3/write_config')
            assert response.success, response.message
    finally:
        stop.set()
        flipper.join(5)
        sys.setswitchinterval(interval)
    assert rig.wait(lambda: len(rig.capture.since(0)) >= 75)
    sent = [bytes(f.data) for _, f in rig.capture.since(0)]
    groups = [tuple(sent[i:i + 5]) for i in range(0, len(sent), 5)]
    assert len(groups) == 15
    seen = [sets.get(group, 'mixed') for group in groups]
    assert 'mixed' not in seen, seen
    assert {'A', 'B'} <= set(seen), seen  # the values really changed between the writes


def test_commands_waiting_for_a_down_bus_leave_telemetry_and_disarming_running(
        rig_factory, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter
    rig = rig_factory({'devices': ['bms16'], 'commands_allowed': True,
                       'commands_enabled': True, 'can.interface': 'slcan',
                       'can.channel': str(tmp_path / 'ttyACM_gone'), 'can.connect_wait': 20.0,
                       'diagnostics_period': 0.1}, wait_connected=False)
    arrays = []
    rig.client.create_subscription(
        DiagnosticArray, '/diagnostics', lambda m: arrays.append(time.monotonic()) if any(
            s.hardware_id == rig.node.hardware_id for s in m.status) else None, 50)
    assert rig.wait(lambda: len(arrays) >= 2)
    calls = [rig.call_in_thread(Trigger, '/bms16/reset_soc') for _ in range(6)]
    assert rig.wait(lambda: sum('response' in c for c in calls) >= 4)
    # 4 answered at once; 2 wait for the bus, each holding an executor thread
    refused = [c['response'].message for c in calls if 'response' in c]
    assert all('2 commands already wait for it' in m for m in refused), refused
    # /diagnostics does not stop (every 0.1 s) while the two calls wait: bounded well below
    # their 20 s bus wait, so they still wait throughout
    start = time.monotonic()
    assert rig.wait(lambda: len([t for t in arrays if t > start]) >= 5, 10.0,
                    '/diagnostics while two calls wait for the bus')
    assert sum('response' in c for c in calls) == 4  # the two still wait
    # the supervisor can still disarm through the parameter service: the waits end at once
    result = rig.call(SetParameters, '/ams_can_bridge/set_parameters', parameters=[
        Parameter('commands_enabled', value=False).to_parameter_msg()])
    assert result.results[0].successful
    for call in calls:
        call['thread'].join(3)
    waited = [c['response'].message for c in calls if 'already wait' not in
              c['response'].message]
    assert len(waited) == 2 and all('commands_enabled was set to false' in m for m in waited)
