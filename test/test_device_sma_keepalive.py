# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The inverter keep-alive 0x305 (sma.inverter_keepalive, doc/protocols.md section 5).

Pylontech's protocol has the inverter reply every second with 0x305, eight zero bytes; a
robot has no inverter, so the bridge sends it: only while commands_enabled and
inverter_keepalive are both true, stopping at once on disarm, start/stop logged once.
"""
import threading

from sensor_msgs.msg import BatteryState

from ams_can_bridge.devices.sma.device import SmaDevice
from ams_can_bridge.devices.sma.keepalive import InverterKeepalive
from ams_can_bridge.protocols.common import Frame
from command_rig import rigs
from helpers import assert_ended, wait_for

ZERO_305 = Frame(0x305, bytes([0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00]))
PERIOD = 0.02  # s, unit tests only; the bridge uses 1 s


class Sink:
    """Records what a keep-alive sends and logs."""

    def __init__(self) -> None:
        self.frames: list[Frame] = []
        self.lines: list[str] = []
        self.lock = threading.Lock()

    def send(self, frame: Frame) -> tuple[bool, str]:
        with self.lock:
            self.frames.append(frame)
        return True, 'sent'

    def count(self) -> int:
        with self.lock:
            return len(self.frames)


def keepalive(sink: Sink) -> tuple[SmaDevice, InverterKeepalive]:
    device = SmaDevice('sma', {})
    return device, device.attach_keepalive(sink.send, sink.lines.append, period=PERIOD)


def test_runs_only_while_armed_and_enabled():
    sink = Sink()
    device, ka = keepalive(sink)
    ka.set_armed(True)  # commands enabled, inverter_keepalive false (the default)
    assert not ka.running
    device.configure({'inverter_keepalive': True})
    assert ka.running
    wait_for(lambda: sink.count() >= 3, 10.0, 'three keep-alives')
    assert set(sink.frames) == {ZERO_305}
    thread = ka.thread
    ka.set_armed(False)
    stopped = sink.count()
    assert not ka.running
    assert_ended(thread, 'the keep-alive')
    assert sink.count() == stopped  # nothing after the disarm returned
    assert device.diagnostic_report().values['inverter keep-alive (0x305)'] == (
        'off: commands_enabled is false')


def test_parameter_off_stops_it_at_once_and_logs_once():
    sink = Sink()
    device, ka = keepalive(sink)
    device.configure({'inverter_keepalive': True})
    assert not ka.running  # not armed yet
    ka.set_armed(True)
    wait_for(lambda: sink.count() >= 5, 10.0, 'five keep-alives')
    assert device.diagnostic_report().values['inverter keep-alive (0x305)'].startswith(
        'sending 0x305 every 0.02 s')
    thread = ka.thread
    device.configure({'inverter_keepalive': False})
    stopped = sink.count()
    assert not ka.running
    assert_ended(thread, 'the keep-alive')
    assert sink.count() == stopped
    # one line for the start, one for the stop: never a line per frame
    assert len(sink.lines) == 2, sink.lines
    assert 'started' in sink.lines[0] and '0x305' in sink.lines[0]
    assert 'stopped' in sink.lines[1] and 'sma.inverter_keepalive is false' in sink.lines[1]


def test_failed_sends_are_counted_not_logged():
    lines = []
    calls = []

    def refuse(frame):
        calls.append(frame)
        return False, 'CAN bus virtual:x is down'
    ka = InverterKeepalive(lambda: ZERO_305, refuse, lines.append, 'sma', PERIOD)
    ka.set_enabled(True)
    ka.set_armed(True)
    wait_for(lambda: len(calls) >= 4, 10.0, 'four attempts')
    assert 'failed, last: CAN bus virtual:x is down' in ka.describe()
    ka.stop('test over')
    assert len(lines) == 2 and 'test over' in lines[1]


def rig_params(enabled=True, keepalive=True):
    return {'devices': ['sma'], 'commands_allowed': True, 'commands_enabled': enabled,
            'sma.inverter_keepalive': keepalive}


def battery(rig):
    return rig.messages('sma/battery_state')


def test_bridge_sends_the_keepalive_only_while_commands_are_enabled():
    with rigs() as make:
        rig = make(rig_params(), topics={'sma/battery_state': BatteryState})
        assert rig.wait(lambda: len(rig.capture.since(0, 0x305)) >= 2, 10.0)
        assert {f for _, f in rig.capture.since(0, 0x305)} == {ZERO_305}
        keepalive = rig.node.devices['sma'].keepalive
        thread = keepalive.thread
        assert rig.set_param('commands_enabled', False).successful
        frames_out = rig.frames_out()
        # stopped with the switch: its thread has ended, nothing came after set_param returned
        assert not keepalive.running
        assert_ended(thread, 'the keep-alive')
        rig.assert_silent_since(frames_out)
        # and the bridge listens on: telemetry still decoded and published
        rig.send(0x356, [0xBE, 0x14, 0xF9, 0xFF, 0x8C, 0x00])
        assert rig.wait(lambda: any(m.present for m in battery(rig)), 10.0)
        assert rig.status('sma', lambda s: any(
            v.key == 'inverter keep-alive (0x305)' and v.value == 'off: commands_enabled is false'
            for v in s.values))


def test_bridge_never_sends_it_by_default(bench_factory):
    bench = bench_factory(rig_params(keepalive=False))
    device = bench.devices['sma']
    assert not device.keepalive.running
    assert bench.set_param('sma.inverter_keepalive', True).successful
    assert bench.wait(lambda: len(bench.capture.since(0, 0x305)) >= 1, 10.0)
    assert bench.set_param('sma.inverter_keepalive', False).successful
    assert not device.keepalive.running
