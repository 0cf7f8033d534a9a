"""The charger role's periodic START (base + 0x010) without ROS: repeat, halt, disarm, bus down."""
import threading
import time

from ams_can_bridge.devices.ams import AmsDevice
from ams_can_bridge.devices.ams_charger import CHARGER_COMMAND_PERIOD, ChargerRepeater
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
