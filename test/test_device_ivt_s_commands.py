# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
IVT-S command sequences of the device against the simulated sensor, in one process, no ROS.

A pump thread plays the bus: the device's commands go to the simulator, the simulator's
frames (results and 0x511 answers) to the device. Expected frames are written by hand.
"""
import threading
import time

import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.ivt_s.device import IvtSDevice
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.ivt_s import IvtMux
from ams_can_bridge.sim.ivt_s import IvtSSimulator
from helpers import wait_for

CYCLES = {'config.i_cycle_ms': 10, 'config.u1_cycle_ms': 20, 'config.u2_cycle_ms': 0,
          'config.u3_cycle_ms': 0, 'config.t_cycle_ms': 100, 'config.w_cycle_ms': 0,
          'config.as_cycle_ms': 1000, 'config.wh_cycle_ms': 0}


class Bus:
    """The device and the simulator on one pretend bus (a pump thread every ms)."""

    def __init__(self, sim, device):
        self.sim, self.device = sim, device
        self.sent: list[Frame] = []
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def send(self, frame):
        with self.lock:
            self.sent.append(frame)
            self.sim.on_frame(frame, time.monotonic())
        return True, 'sent'

    def _run(self):
        while not self._stop.wait(0.001):
            with self.lock:
                frames = self.sim.tick(time.monotonic())
            for frame in frames:
                self.device.handle_frame(frame.arbitration_id, frame.data, time.time())

    def commands(self):
        with self.lock:
            return [f.data for f in self.sent]

    def close(self):
        self._stop.set()
        self._thread.join(2)


@pytest.fixture
def rig():
    made = []

    def make(sim=None, **params):
        sim = sim or IvtSSimulator(period=0.02)
        device = IvtSDevice('ivt_s', {'command_timeout': 3.0, **params})  # a loaded machine
        bus = Bus(sim, device)
        made.append(bus)
        wait_for(device.heard, 5.0, 'the first result')
        return sim, device, bus
    yield make
    for bus in made:
        bus.close()


def test_read_config_of_a_factory_sensor_matches(rig):
    sim, device, bus = rig()
    ok, message = device.read_config(bus.send)
    assert ok, message
    assert message == ('ivt_s: read_config: RUN; I 20 ms, U1 20 ms, U2 20 ms, U3 20 ms, '
                       'T 20 ms, W 20 ms, As 20 ms, Wh 20 ms; big-endian; sign normal; '
                       'error masks off; matches the bridge')
    assert bus.commands() == [bytes([0x74] + [0] * 7)] + [
        bytes([0x60 + k] + [0] * 7) for k in range(8)]
    diag = device.diagnostic_report()
    assert diag.level == Level.OK and diag.values['config check'].startswith('ok')
    assert diag.values['sensor mode'] == 'RUN, after power-up RUN'
    assert diag.values['I config'] == 'cyclic 20 ms, big-endian, sign normal'


def test_little_endian_sensor_is_an_error_naming_byte_order(rig):
    sim = IvtSSimulator(period=0.02, byte_order='little')
    sim, device, bus = rig(sim)  # the bridge expects big (factory) by default
    ok, message = device.read_config(bus.send)
    assert not ok
    assert ('little-endian; sign normal; error masks off; MISMATCH: the sensor sends its '
            'results little-endian, ivt_s.byte_order is big: set ivt_s.byte_order to little'
            in message)
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR and 'set ivt_s.byte_order to little' in diag.message


def test_inverted_current_sign_is_an_error_naming_discharge_positive(rig):
    sim = IvtSSimulator(period=0.02)
    sim.misconfigure(sign_inverted=True)
    sim, device, bus = rig(sim)
    ok, message = device.read_config(bus.send)
    assert not ok and 'sign inverted' in message
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert ('the sensor sends I, W, As, Wh with sign inverted, so discharging current '
            'arrives negative while ivt_s.discharge_positive is true: set '
            'ivt_s.discharge_positive to false') in diag.message
    assert 'U1, U2, U3, T with sign inverted (negated values)' in diag.message


def test_mounted_reversed_expects_the_sign_inverted(rig):
    sim = IvtSSimulator(period=0.02)
    sim.misconfigure(sign_inverted=True)
    for kind in (IvtMux.U1, IvtMux.U2, IvtMux.U3, IvtMux.T):
        sim.configs[kind] = sim.factory[kind]
    sim, device, bus = rig(sim, mounted_reversed=True)
    ok, message = device.read_config(bus.send)
    assert ok, message


def test_write_config_then_read_back_reports_what_was_written(rig):
    sim = IvtSSimulator(period=0.02, current_fn=lambda t: 12.5)
    sim, device, bus = rig(sim, byte_order='little', **CYCLES)
    ok, message = device.write_config(bus.send)
    assert ok, message
    assert message == (
        'ivt_s: write_config: stopped, wrote 8 results, stored, running; read back: RUN; '
        'I 10 ms, U1 20 ms, U2 off, U3 off, T 100 ms, W off, As 1000 ms, Wh off; '
        'little-endian; sign normal; error masks off')
    commands = bus.commands()
    assert commands[0] == bytes([0x60] + [0] * 7)  # error_masks unset: the sensor's kept
    commands = commands[1:]
    assert commands[:11] == [
        bytes([0x34, 0x00, 0x01, 0, 0, 0, 0, 0]),
        bytes([0x20, 0x42, 0x00, 0x0A, 0, 0, 0, 0]),  # I cyclic 10 ms little-endian
        bytes([0x21, 0x42, 0x00, 0x14, 0, 0, 0, 0]),
        bytes([0x22, 0x40, 0x00, 0x3C, 0, 0, 0, 0]),  # U2 off (time 60, as ivts writes it)
        bytes([0x23, 0x40, 0x00, 0x3C, 0, 0, 0, 0]),
        bytes([0x24, 0x42, 0x00, 0x64, 0, 0, 0, 0]),
        bytes([0x25, 0x40, 0x00, 0x3C, 0, 0, 0, 0]),
        bytes([0x26, 0x42, 0x03, 0xE8, 0, 0, 0, 0]),
        bytes([0x27, 0x40, 0x00, 0x3C, 0, 0, 0, 0]),
        bytes([0x32, 0, 0, 0, 0, 0, 0, 0]),
        bytes([0x34, 0x01, 0x01, 0, 0, 0, 0, 0])]
    assert commands[11:] == [bytes([0x74] + [0] * 7)] + [
        bytes([0x60 + k] + [0] * 7) for k in range(8)]
    assert sim.stored == sim.configs  # survives a restart
    ok, again = device.read_config(bus.send)
    assert ok and again == ('ivt_s: read_config: ' + message.split('read back: ')[1]
                            + '; matches the bridge')
    # the results now come little-endian, and the device decodes them
    wait_for(lambda: device.current_a() == -12.5, 2.0, 'the current decoded little-endian')


def test_write_config_with_discharge_negative_inverts_the_directional_results(rig):
    sim, device, bus = rig(discharge_positive=False, **CYCLES)
    ok, message = device.write_config(bus.send)
    assert ok, message
    assert 'sign inverted (I, W, As, Wh) / sign normal (U1, U2, U3, T)' in message
    assert bus.commands()[2] == bytes([0x20, 0x82, 0x00, 0x0A, 0, 0, 0, 0])


def test_write_config_keeps_the_sensors_error_masks_when_unset(rig):
    """
    Bit 5 of the configuration byte is global (the datasheet): kept unless configured.

    Frames by hand: 0x60 asks the I configuration; A0 22 00 14 = cyclic (2) | bit 5 (0x20),
    20 ms; then 0x20.. with byte 1 = 0x62: cyclic | bit 5 | little-endian (0x40).
    """
    sim = IvtSSimulator(period=0.02)
    sim.misconfigure(error_masks=True)  # set up so by another tool
    sim, device, bus = rig(sim, byte_order='little', **CYCLES)
    ok, message = device.read_config(bus.send)
    assert 'big-endian; sign normal; error masks on; MISMATCH' in message
    assert device.diagnostic_report().values['I config'] == (
        'cyclic 20 ms, big-endian, sign normal, error masks in the result state')
    mark = len(bus.commands())
    ok, message = device.write_config(bus.send)
    assert ok, message
    assert message.endswith('little-endian; sign normal; error masks on')
    commands = bus.commands()[mark:]
    assert commands[:3] == [bytes([0x60] + [0] * 7), bytes([0x34, 0x00, 0x01, 0, 0, 0, 0, 0]),
                            bytes([0x20, 0x62, 0x00, 0x0A, 0, 0, 0, 0])]
    assert commands[3] == bytes([0x21, 0x62, 0x00, 0x14, 0, 0, 0, 0])
    assert all(config.error_masks for config in sim.stored.values())


@pytest.mark.parametrize('masks, byte1, shown', [(False, 0x42, 'off'), (True, 0x62, 'on')])
def test_write_config_sets_the_error_masks_when_configured(rig, masks, byte1, shown):
    sim = IvtSSimulator(period=0.02)
    sim.misconfigure(error_masks=not masks)
    sim, device, bus = rig(sim, byte_order='little', **CYCLES, **{'config.error_masks': masks})
    ok, message = device.write_config(bus.send)
    assert ok, message
    assert message.endswith(f'little-endian; sign normal; error masks {shown}')
    commands = bus.commands()
    assert commands[:2] == [bytes([0x34, 0x00, 0x01, 0, 0, 0, 0, 0]),
                            bytes([0x20, byte1, 0x00, 0x0A, 0, 0, 0, 0])]
    assert {config.error_masks for config in sim.configs.values()} == {masks}


def test_write_config_refuses_unset_values_and_sends_nothing(rig):
    sim, device, bus = rig(**{'config.i_cycle_ms': 10})
    ok, message = device.write_config(bus.send)
    assert not ok
    assert message == (
        'ivt_s: write_config refused: 7 value(s) unset: ivt_s.config.u1_cycle_ms, '
        'ivt_s.config.u2_cycle_ms, ivt_s.config.u3_cycle_ms, ivt_s.config.t_cycle_ms, '
        'ivt_s.config.w_cycle_ms, ivt_s.config.as_cycle_ms, ivt_s.config.wh_cycle_ms (cycle '
        'time in ms, 0 = off); nothing was sent')
    assert bus.commands() == [] and sim.received == []


def test_cycle_values_out_of_range_are_refused_when_set():
    device = IvtSDevice('ivt_s', {})
    assert device.config_reason('config.i_cycle_ms', 70000) == (
        'ivt_s.config.i_cycle_ms = 70000 refused: allowed a whole number of ms 0..65535 '
        '(0 = off)')
    assert device.config_reason('config.as_cycle_ms', 0) is None
    assert device.config_reason('config.as_cycle_ms', 1000.0) is None  # YAML 1000.0 = 1000
    assert 'allowed a whole number' in device.config_reason('config.as_cycle_ms', 10.5)
    with pytest.raises(ValueError, match='ivt_s.config.t_cycle_ms'):
        IvtSDevice('ivt_s', {'config.t_cycle_ms': -1})


def test_no_answer_fails_within_command_timeout_naming_the_step(rig):
    sim, device, bus = rig(command_timeout=0.5)
    sim.faults.extra['mute_commands'] = True
    started = time.monotonic()
    ok, message = device.read_config(bus.send)
    assert not ok and time.monotonic() - started < 5.0
    assert message == ('ivt_s: read the configuration failed: no answer to GET_MODE (0x74) '
                       'within 0.5 s')


def test_write_stopped_then_silent_tries_to_run_again(rig):
    sim, device, bus = rig(command_timeout=0.5, **CYCLES, **{'config.error_masks': False})
    sim.faults.extra['mute_commands'] = True
    ok, message = device.write_config(bus.send)
    assert not ok
    assert message.startswith('ivt_s: write the configuration failed: no answer to stop '
                              '(SET_MODE) (0x34) within 0.5 s; done before: nothing')
    assert bus.commands() == [bytes([0x34, 0, 1, 0, 0, 0, 0, 0])]


def test_set_running_stops_and_starts_the_results(rig):
    sim, device, bus = rig()
    ok, message = device.set_running(bus.send, False)
    assert ok and message == 'ivt_s: set_running: the sensor reports STOP'
    assert not sim.running
    assert device.diagnostic_report().values['sensor mode'] == 'STOP, after power-up RUN'
    wait_for(device.is_stale, 5.0, 'the results to stop')
    ok, message = device.set_running(bus.send, True)
    assert ok and 'RUN' in message
    wait_for(lambda: not device.is_stale(), 5.0, 'the results again')


def test_restart_waits_for_the_alive_message(rig):
    sim, device, bus = rig()
    ok, message = device.restart(bus.send)
    assert ok, message
    assert message == ('ivt_s: restart: alive again (serial 74565); the As and Wh counters '
                       'start from 0')
    assert bus.commands() == [bytes([0x3F] + [0] * 7)]
    assert device.diagnostic_report().values['alive after restart'].startswith('1 time(s)')


def test_reset_errors_stops_resets_with_the_serial_number_and_runs_again(rig):
    """
    The datasheet allows 0x30 only in Stop mode and answers it in Run mode too.

    Frames by hand: 0x7B; 0x34 b1 0 (STOP now) b2 1 (RUN after power-up); 0x30 b1..2 the
    item (0x0000 all measurement errors, 0x0100 all system errors), b3..6 the serial number
    (74565 = 0x00012345); 0x34 01 01.
    """
    sim, device, bus = rig()
    sim.faults.error_code = 3  # system error bit on every result
    wait_for(lambda: device.diagnostic_report().level == Level.ERROR, 5.0, 'the error')
    ok, message = device.reset_errors(bus.send)
    assert ok, message
    assert message == ('ivt_s: reset_errors: stopped, reset all measurement errors, reset all '
                       'system errors, running (serial 74565)')
    assert bus.commands() == [bytes([0x7B] + [0] * 7),
                              bytes([0x34, 0x00, 0x01, 0, 0, 0, 0, 0]),
                              bytes([0x30, 0x00, 0x00, 0x00, 0x01, 0x23, 0x45, 0]),
                              bytes([0x30, 0x01, 0x00, 0x00, 0x01, 0x23, 0x45, 0]),
                              bytes([0x34, 0x01, 0x01, 0, 0, 0, 0, 0])]
    assert sim.running
    wait_for(lambda: device.diagnostic_report().level == Level.OK, 5.0, 'the error cleared')


def answering(bus, device, mux, answer):
    """Return a send that answers commands ``mux`` with ``answer`` (hex) instead of the sim."""
    def send(frame):
        if frame.data[0] == mux:
            device.handle_frame(0x511, bytes.fromhex(answer), time.time())
            return True, 'sent'
        return bus.send(frame)
    return send


def test_reset_errors_refused_while_stopped_puts_the_sensor_back_into_run(rig):
    sim, device, bus = rig()
    sim.faults.error_code = 3
    refusing = answering(bus, device, 0x30, 'FF 30 00 00 00 00 00 00')  # "wrong command"
    ok, message = device.reset_errors(refusing)
    assert not ok
    assert message == ('ivt_s: reset the errors failed: the sensor refused reset all '
                       'measurement errors (0x30): wrong command (0xFF); done before: '
                       'stopped; the sensor was put back into RUN')
    assert bus.commands()[-1] == bytes([0x34, 0x01, 0x01, 0, 0, 0, 0, 0]) and sim.running
    assert sim.faults.error_code == 3  # nothing was reset


def test_reset_errors_is_not_sent_when_the_sensor_stays_in_run(rig):
    sim, device, bus = rig()
    staying = answering(bus, device, 0x34, 'B4 01 01 00 00 00 00 00')  # stop answered RUN
    ok, message = device.reset_errors(staying)
    assert not ok
    assert message == ('ivt_s: reset the errors failed: the sensor answered stop (0x34) but '
                       'stays in RUN; done before: nothing')
    assert [f[0] for f in bus.commands()] == [0x7B]  # no 0x30 went out


def test_unknown_and_malformed_answers_are_counted_never_fatal():
    device = IvtSDevice('ivt_s', {})
    assert device.handle_frame(0x511, bytes([0x90, 1, 2, 3, 4, 5, 6, 7]), 0.0) is False
    assert device.handle_frame(0x511, bytes([0xB4, 1]), 0.0) is False  # DLC 2
    assert device.handle_frame(0x511, bytes([0xFF, 0x99, 0, 0, 0, 0, 0, 0]), 0.0) is False
    assert device.handle_frame(0x511, bytes([0x81, 5, 0, 1, 0, 0, 0, 0]), 0.0) is False
    values = device.diagnostic_report().values
    assert values['unknown answers'] == '1, last 90 01 02 03 04 05 06 07'
    assert values['wrong command answers'] == '1, last for command 0x99'
    assert values['last error item'] == 'system error item 5 (overtemperature): 0x0001'
    assert values['frames malformed'] == '1' and 'DLC 2' in values['last malformed frame']
    assert values['config check'] == 'not read (read_config)'


def test_a_second_sequence_waits_for_none(rig):
    sim, device, bus = rig(command_timeout=0.5)
    sim.faults.extra['mute_commands'] = True
    first = threading.Thread(target=device.read_config, args=(bus.send,))
    first.start()
    wait_for(lambda: bus.commands(), 2.0, 'the first command')
    ok, message = device.restart(bus.send)
    first.join(5)
    assert not ok and 'another IVT-S command is running' in message


def test_a_second_sensor_is_commanded_on_its_own_ids():
    """
    command_id / answer_id: a second IVT-S on the bus, set to 0x412 / 0x512 in the sensor.

    Its commands go out on 0x412 (the protocol builds them on 0x411); it listens on 0x512,
    not on the factory 0x511 (another sensor's), and the answer there completes the call.
    """
    device = IvtSDevice('rear', {'base_id': 0x621, 'command_id': 0x412, 'answer_id': 0x512,
                                 'command_timeout': 3.0})
    assert (0x512, False) in device.frame_ids and (0x511, False) not in device.frame_ids
    device.handle_frame(0x621, bytes([0x00, 0x01, 0, 0, 0x03, 0xE8]), time.time())  # I 1 A
    sent: list[Frame] = []
    answer = bytes([0xB4, 0x00, 0x01, 0, 0, 0, 0, 0])  # mode answer: STOP, power-up RUN

    def send(frame):
        sent.append(frame)
        threading.Timer(0.05, lambda: device.handle_frame(0x512, answer, time.time())).start()
        return True, 'sent'
    ok, message = device.set_running(send, False)
    assert ok, message
    assert [(f.arbitration_id, f.data[:2]) for f in sent] == [(0x412, bytes([0x34, 0x00]))]
    assert message == 'rear: set_running: the sensor reports STOP'


def test_an_answer_id_among_the_result_ids_is_refused():
    with pytest.raises(ValueError, match='rear.answer_id = 0x622 is one of its result IDs'):
        IvtSDevice('rear', {'base_id': 0x621, 'answer_id': 0x622})
