# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The charger role's START (base + 0x010) without ROS: repeat, halt, disarm, bus down, order.

The ordering rule (no START ever after a STOP) is the device's (devices/ams/charger.py): its
two services run one at a time, and the repeat has ended before the STOP is sent.
"""
import threading
import time

from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.devices.ams.charger import CHARGER_COMMAND_PERIOD, ChargerRepeater
from helpers import wait_for


class Logger:
    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(('info', text))

    def warning(self, text):
        self.lines.append(('warning', text))


class Bus:
    """The far end: keeps every frame with its time; can be pulled out."""

    def __init__(self):
        self.lock = threading.Lock()
        self.frames = []
        self.down = ''

    def send(self, frame):
        with self.lock:
            if self.down:
                return False, self.down
            self.frames.append((time.monotonic(), frame))
            return True, ''

    def data(self):
        with self.lock:
            return [f.data for _, f in self.frames]


def repeat_threads():
    """Charger repeat threads alive now (none = nothing can be sent any more)."""
    return [t for t in threading.enumerate() if t.name == 'ams-charger-start' and t.is_alive()]


def make(period=0.01):
    bus, log = Bus(), Logger()
    ticks = iter(range(0x1000, 0x10000))
    device = AmsDevice('ams', {})
    repeater = ChargerRepeater(device.charger_frame, bus.send, lambda: next(ticks), log,
                               period=period)
    return repeater, bus, log


def test_the_seed_period_is_100_ms():
    assert CHARGER_COMMAND_PERIOD == 0.1
    repeater = AmsDevice('ams', {}).attach_charger(Bus().send, lambda: 0, Logger())
    assert repeater.period == 0.1 and not repeater.armed and not repeater.active


def test_start_is_repeated_with_a_fresh_tick_and_logged_once():
    repeater, bus, log = make()
    repeater.arm()
    assert repeater.begin() == ''
    wait_for(lambda: len(bus.frames) >= 10, 5.0, '10 repeats')
    data = bus.data()
    # 0x310 (base 0x300 + 0x010), DLC 3: b0 = 1 START, b1..2 = time tick, big-endian
    assert all(f.arbitration_id == 0x310 for _, f in bus.frames)
    assert data[:3] == [bytes([1, 0x10, 0x00]), bytes([1, 0x10, 0x01]), bytes([1, 0x10, 0x02])]
    assert repeater.begin() == ''  # already active: no second thread
    assert repeater.halt('stop_charging') is True
    assert not repeat_threads() and not repeater.active  # halt() joined it
    assert [level for level, _ in log.lines] == ['info', 'info']  # start, stop: not per frame
    assert 'repeated every 10 ms' in log.lines[0][1]
    assert 'no longer repeated (stop_charging)' in log.lines[1][1]
    assert repeater.halt('again') is False and len(log.lines) == 2


def test_disarm_stops_at_once_and_refuses_until_armed_again():
    repeater, bus, log = make()
    assert 'commands_enabled is false' in repeater.begin()  # never armed
    repeater.arm()
    repeater.begin()
    wait_for(lambda: len(bus.frames) >= 3, 5.0, '3 repeats')
    assert repeater.disarm('commands_enabled was set to false') is True
    assert not repeat_threads()  # halt() joined it: nothing in flight, nothing to come
    assert 'commands_enabled is false' in repeater.begin()
    repeater.arm()  # re-arming resumes nothing
    assert not repeat_threads() and not repeater.active
    assert repeater.last_stop == 'commands_enabled was set to false'


def test_a_repeat_that_cannot_be_sent_drops_the_request_for_good():
    repeater, bus, log = make()
    repeater.arm()
    repeater.begin()
    wait_for(lambda: len(bus.frames) >= 2, 5.0, '2 repeats')
    bus.down = 'CAN bus virtual:x is not connected (reconnecting: unplugged)'
    wait_for(lambda: not repeater.active and not repeat_threads(), 5.0, 'the repeat to end')
    bus.down = ''  # the bus returns: no thread is left to send anything stale
    warnings = [text for level, text in log.lines if level == 'warning']
    assert len(warnings) == 1 and 'not connected' in warnings[0]
    assert 'call start_charging again' in warnings[0]
    assert 'a repeat was not sent' in repeater.last_stop


def test_the_device_shows_the_repeat_in_its_diagnostics():
    device = AmsDevice('ams', {})
    bus = Bus()
    repeater = device.attach_charger(bus.send, lambda: 0, Logger())
    assert device.diagnostic_report().values['charger START repeated'] == 'no'
    repeater.arm()
    repeater.begin()
    assert device.diagnostic_report().values['charger START repeated'].startswith(
        'yes, every 100 ms')
    repeater.disarm('commands_enabled was set to false')
    assert device.diagnostic_report().values['charger START repeated'] == (
        'no (last: commands_enabled was set to false)')


class Port:
    """The pipeline's port as the charger uses it: send_frames builds and sends on the bus."""

    def __init__(self, bus):
        self.bus = bus
        self.hold = None  # an Event: the next send_frames waits for it
        self.holding = threading.Event()

    def send_frames(self, build):
        frames = list(build())
        if self.hold is not None:
            hold, self.hold = self.hold, None
            self.holding.set()
            hold.wait(5.0)
        for frame in frames:
            ok, why = self.bus.send(frame)
            if not ok:
                return False, f'ams: failed: {why}'
        return True, 'ams: start charging: sent'


def starts_and_stops(bus):
    """Return b0 (1 START, 2 STOP) of every charger frame on the bus, in order."""
    return [d[0] for d in bus.data()]


def test_stop_charging_ends_the_repeat_before_its_stop_goes_out():
    repeater, bus, log = make()
    repeater.arm()
    port = Port(bus)
    ok, message = repeater.start_charging(port)
    assert ok and message == ('ams: start charging: sent, repeated every 10 ms until '
                              'stop_charging or commands_enabled false')
    wait_for(lambda: len(bus.frames) >= 5, 5.0, 'repeats')
    again = repeater.start_charging(port)  # already repeating: nothing more is sent
    assert again == (True, 'ams: start charging: START is already repeated every 10 ms; '
                           'nothing more sent')
    seen_at_stop = []
    real = port.send_frames

    def stop_sent(build):
        seen_at_stop.append((repeater.active, bool(repeat_threads())))
        return real(build)
    port.send_frames = stop_sent
    ok, message = repeater.stop_charging(port)
    assert ok and message.endswith('; the repeated START has ended')
    assert seen_at_stop == [(False, False)]  # no repeat could follow the STOP
    assert starts_and_stops(bus)[-1] == 2 and set(starts_and_stops(bus)[:-1]) == {1}


def test_a_stop_called_while_a_start_is_under_way_waits_for_it_and_comes_last():
    repeater, bus, log = make()
    repeater.arm()
    port = Port(bus)
    port.hold = release = threading.Event()
    start = threading.Thread(target=lambda: repeater.start_charging(port), daemon=True)
    start.start()
    assert port.holding.wait(5.0)  # the START is being sent, its repeat not begun yet
    stop = threading.Thread(target=lambda: repeater.stop_charging(Port(bus)), daemon=True)
    stop.start()
    stop.join(0.2)
    assert stop.is_alive()  # one call at a time: the stop waits for the start
    release.set()
    start.join(5.0)
    stop.join(5.0)
    assert not start.is_alive() and not stop.is_alive()
    assert not repeat_threads() and not repeater.active
    # START first, the STOP last: the repeat the start began was ended by the stop
    frames = starts_and_stops(bus)
    assert frames[0] == 1 and frames[-1] == 2 and 2 not in frames[:-1], frames
