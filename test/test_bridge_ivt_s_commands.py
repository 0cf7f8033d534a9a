# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
IVT-S services against the simulated IVT-S.

On a real node over slcan (the test plays the USB-CAN adapter and carries the simulator's
frames), and through the one command pipeline without ROS (``bench_factory``) on a virtual
bus.

Refused calls are proven silent with a marker frame: it is sent after the call and waited
for, and no 0x411 frame may come before it.
"""
import threading
import time

import can
import pytest
from std_srvs.srv import SetBool, Trigger

from ams_can_bridge.sim.ivt_s import IvtSSimulator
from ams_can_bridge.sim.runner import SimRunner
from slcan_peer import SlcanPeer

CYCLES = {'ivt_s.config.i_cycle_ms': 10, 'ivt_s.config.u1_cycle_ms': 20,
          'ivt_s.config.u2_cycle_ms': 0, 'ivt_s.config.u3_cycle_ms': 0,
          'ivt_s.config.t_cycle_ms': 100, 'ivt_s.config.w_cycle_ms': 0,
          'ivt_s.config.as_cycle_ms': 1000, 'ivt_s.config.wh_cycle_ms': 0}


def params(enabled=True, **more):
    return {'devices': ['ivt_s'], 'commands_allowed': True, 'commands_enabled': enabled,
            'diagnostics_period': 0.2, 'ivt_s.command_timeout': 3.0, **more}


def level(status):
    return status.level[0] if isinstance(status.level, bytes) else status.level


class SlcanSim:
    """The simulator behind a pty slcan adapter: what the bridge sends reaches it."""

    def __init__(self, peer, sim):
        self.peer, self.sim = peer, sim
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        while not self._stop.wait(0.002):
            now = time.monotonic()
            for frame in self.peer.received(clear=True):
                self.sim.on_frame(frame, now)
            if self.peer.is_open:
                for frame in self.sim.tick(now):
                    self.peer.send(frame)

    def close(self):
        self._stop.set()
        self._thread.join(2)


@pytest.fixture
def slcan_rig(rig_factory, tmp_path):
    """Yield a maker: (bridge params, simulator) -> rig on slcan with the simulator behind."""
    made = []

    def make(bridge_params, sim):
        peer = SlcanPeer(symlink=tmp_path / f'ttyIVT{len(made)}')
        link = SlcanSim(peer, sim)
        made.append((peer, link))
        rig = rig_factory({'can.interface': 'slcan', 'can.channel': peer.channel,
                           'can.options': ['sleep_after_open=0'], **bridge_params})
        peer.wait_open()
        return rig, peer
    yield make
    for peer, link in made:
        link.close()
        peer.shutdown()


@pytest.fixture
def sim_on():
    """Yield a starter of simulated IVT-S on a rig's virtual channel."""
    started = []

    def start(rig, sim):
        bus = can.Bus(interface='virtual', channel=rig.channel)
        runner = SimRunner(bus, [sim], tick_period=0.002)
        runner.start()
        started.append((runner, bus))
        return sim
    yield start
    for runner, bus in started:
        runner.stop()
        bus.shutdown()


def commands_before_marker(rig):
    """Send a marker frame, wait until the capture has it; return the 0x411 frames before."""
    rig.capture.sync()
    return [f for _, f in rig.capture.since(0, 0x411)]


# --- over slcan: every service end to end -------------------------------------------------
def test_services_end_to_end_over_slcan(slcan_rig):
    sim = IvtSSimulator(period=0.02, current_fn=lambda t: 12.5)
    rig, peer = slcan_rig(params(**CYCLES, **{'ivt_s.byte_order': 'little'}), sim)
    rig.wait(lambda: rig.node.devices['ivt_s'].heard(), 10.0, 'the simulated IVT-S')

    read = rig.call(Trigger, '/ivt_s/read_config')  # factory: big-endian, bridge: little
    assert not read.success
    assert 'MISMATCH: the sensor sends its results big-endian, ivt_s.byte_order is little: ' \
           'set ivt_s.byte_order to big' in read.message

    write = rig.call(Trigger, '/ivt_s/write_config', timeout=30.0)
    assert write.success, write.message
    assert write.message.endswith(
        'read back: RUN; I 10 ms, U1 20 ms, U2 off, U3 off, T 100 ms, W off, As 1000 ms, '
        'Wh off; little-endian; sign normal; error masks off')
    read = rig.call(Trigger, '/ivt_s/read_config')
    assert read.success, read.message
    assert read.message == ('ivt_s: read_config: RUN; I 10 ms, U1 20 ms, U2 off, U3 off, '
                            'T 100 ms, W off, As 1000 ms, Wh off; little-endian; sign normal; '
                            'error masks off; matches the bridge')
    status = rig.status('ivt_s', lambda s: level(s) == 0 and '-12.50 A' in s.message, 10.0)
    values = {kv.key: kv.value for kv in status.values}
    assert values['config check'].startswith('ok')
    assert values['As config'] == 'cyclic 1000 ms, little-endian, sign normal'

    stop = rig.call(SetBool, '/ivt_s/set_running', data=False)
    assert stop.success and stop.message == 'ivt_s: set_running: the sensor reports STOP'
    rig.status('ivt_s', lambda s: level(s) == 3, 10.0)  # no results: STALE
    start = rig.call(SetBool, '/ivt_s/set_running', data=True)
    assert start.success, start.message
    rig.status('ivt_s', lambda s: level(s) == 0, 10.0)

    restart = rig.call(Trigger, '/ivt_s/restart')
    assert restart.success and 'alive again (serial 74565)' in restart.message
    sim.faults.error_code = 7
    rig.status('ivt_s', lambda s: level(s) == 2 and 'System_Error' in s.message, 10.0)
    reset = rig.call(Trigger, '/ivt_s/reset_errors')
    assert reset.success, reset.message
    assert reset.message == ('ivt_s: reset_errors: stopped, reset all measurement errors, '
                             'reset all system errors, running (serial 74565)')
    rig.status('ivt_s', lambda s: level(s) == 0, 10.0)
    # what crossed the adapter, in the order the bridge sent it (golden bytes by hand)
    sent = [data for _, data in sim.received]
    reads = [bytes([0x74] + [0] * 7)] + [bytes([0x60 + k] + [0] * 7) for k in range(8)]
    assert sent[:9] == reads
    assert sent[9] == bytes([0x60] + [0] * 7)  # error_masks unset: the sensor's is kept
    assert sent[10] == bytes([0x34, 0x00, 0x01, 0, 0, 0, 0, 0])
    assert sent[11] == bytes([0x20, 0x42, 0x00, 0x0A, 0, 0, 0, 0])
    assert sent[-5:] == [bytes([0x7B] + [0] * 7),
                         bytes([0x34, 0x00, 0x01, 0, 0, 0, 0, 0]),  # 0x30 only in STOP
                         bytes([0x30, 0x00, 0x00, 0x00, 0x01, 0x23, 0x45, 0]),
                         bytes([0x30, 0x01, 0x00, 0x00, 0x01, 0x23, 0x45, 0]),
                         bytes([0x34, 0x01, 0x01, 0, 0, 0, 0, 0])]
    assert rig.failures == []


def test_check_config_at_start_detects_little_endian_over_slcan(slcan_rig):
    sim = IvtSSimulator(period=0.02, byte_order='little')
    rig, peer = slcan_rig(params(**{'ivt_s.check_config_at_start': True}), sim)
    status = rig.status('ivt_s', lambda s: level(s) == 2, 15.0)
    assert 'set ivt_s.byte_order to little' in status.message
    assert [mux for mux, _ in sim.received] == [0x74] + list(range(0x60, 0x68))


# --- refusals: nothing sent ------------------------------------------------------------------
@pytest.mark.parametrize('service, data', [
    ('read_config', None), ('write_config', None), ('restart', None), ('reset_errors', None),
    ('set_running', False)])
def test_refused_while_commands_are_disabled_sends_nothing(bench_factory, sim_on, service,
                                                           data):
    bench = bench_factory(params(enabled=False, **CYCLES))
    sim = sim_on(bench, IvtSSimulator(period=0.05))
    response = bench.call(f'/ivt_s/{service}', data)
    assert not response.success
    assert 'commands_enabled is false' in response.message
    assert 'nothing was sent' in response.message
    assert commands_before_marker(bench) == [] and sim.received == []


def test_write_config_with_unset_values_is_refused_and_sends_nothing(bench_factory, sim_on):
    bench = bench_factory(params(**{'ivt_s.config.i_cycle_ms': 10}))
    sim = sim_on(bench, IvtSSimulator(period=0.05))
    response = bench.call('/ivt_s/write_config')
    assert not response.success
    assert 'ivt_s.config.u1_cycle_ms' in response.message
    assert 'nothing was sent' in response.message
    assert commands_before_marker(bench) == [] and sim.received == []


def test_no_sensor_answer_fails_after_command_timeout(bench_factory):
    bench = bench_factory(params(**{'ivt_s.command_timeout': 0.3}))  # nobody on the bus
    response = bench.call('/ivt_s/restart')
    assert not response.success
    assert response.message == ('ivt_s: restart failed: no answer to RESTART (0x3F) within '
                                '0.3 s')


def test_check_config_at_start_sends_nothing_while_disabled(bench_factory, sim_on):
    bench = bench_factory(params(enabled=False, **{'ivt_s.check_config_at_start': True}))
    device = bench.devices['ivt_s']
    looks = []  # each time the start check found the sensor heard
    heard = device.heard

    def spied():
        result = heard()
        if result and threading.current_thread().name == 'ivt_s-check':
            looks.append(result)
        return result
    device.heard = spied  # the check thread looks it up at each poll
    sim = sim_on(bench, IvtSSimulator(period=0.02, byte_order='little'))
    check = bench.commands.start_checks['ivt_s']
    # the check had its chances: it saw the sensor heard three times while disabled
    bench.wait(lambda: len(looks) >= 3 or check.outcome, 10.0,
               'the start check to see the simulated IVT-S')
    assert check.outcome is None  # it did not run
    assert commands_before_marker(bench) == [] and sim.received == []
    assert bench.set_param('commands_enabled', True).successful  # armed: the check runs now
    bench.wait(lambda: device.diagnostic_report().level == 2, 10.0, 'the mismatch (ERROR)')
    assert 'set ivt_s.byte_order to little' in device.diagnostic_report().message


def test_parameters_are_declared_with_ranges(rig_factory):
    rig = rig_factory({'devices': ['ivt_s']})
    [cycle] = rig.node.describe_parameters(['ivt_s.config.as_cycle_ms'])
    assert cycle.integer_range[0].from_value == 0 and cycle.integer_range[0].to_value == 65535
    assert rig.node.get_parameter('ivt_s.config.as_cycle_ms').value is None
    assert rig.node.get_parameter('ivt_s.command_timeout').value == 2.0
    assert rig.node.get_parameter('ivt_s.check_config_at_start').value is False
    assert rig.node.devices['ivt_s'].config.value('config.error_masks') is None  # kept
    assert rig.set_param('ivt_s.config.error_masks', True).successful
    assert rig.node.devices['ivt_s'].config.value('config.error_masks') is True
    assert rig.set_param('ivt_s.config.i_cycle_ms', 70000).successful is False
    assert rig.set_param('ivt_s.config.i_cycle_ms', 10).successful is True
