# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""IVT-S simulator: schedule, counters, consistent physics, both byte orders, faults."""
import math
import time

import can
import pytest

from ams_can_bridge import registry
from ams_can_bridge.devices.ivt_s.device import IvtSDevice
from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.ivt_s import IvtMux, IvtSCodec
from ams_can_bridge.protocols.ivt_s_commands import decode_answer, ErrorAnswer
from ams_can_bridge.sim.ivt_s import IvtSSimulator


def run(sim, codec, seconds, period=0.1, step=0.05):
    """Tick the model every ``step`` s; return [(now, {kind: IvtResult})] per period."""
    out = []
    for n in range(int(round(seconds / step)) + 1):
        now = n * step
        frames = sim.tick(now)
        if frames:
            out.append((now, {r.kind: r for r in (codec.decode(f.arbitration_id, f.data)
                                                  for f in frames)}))
    return out


def test_registry_and_type():
    cls = registry.load(registry.SIMULATORS['ivt_s'])
    assert cls is IvtSSimulator and cls.TYPE == 'ivt_s'
    assert IvtSSimulator().name == 'ivt_s'


def test_all_eight_results_once_per_period_with_counters_like_a_real_sensor():
    """
    Every 100 ms, and each counter advances by 5 per frame, as a real IVT-S's do.

    Golden: the Wh counters of foxBMS 2's trace (test/fixtures/foxbms2, 0x528, one frame
    every 100 ms): 05 0a 0f 04 09 0e 03 08 0d 02 07 0c 01 06 0b 00.
    """
    sim = IvtSSimulator()
    codec = IvtSCodec()
    periods = run(sim, codec, 2.0)
    assert len(periods) == 21  # t = 0, 0.1, ..., 2.0; nothing at the 0.05 s ticks
    for _, results in periods:
        assert set(results) == set(IvtMux)
        assert len({r.counter for r in results.values()}) == 1  # every result alike here
    trace_wh = [0x05, 0x0A, 0x0F, 0x04, 0x09, 0x0E, 0x03, 0x08, 0x0D, 0x02, 0x07, 0x0C, 0x01,
                0x06, 0x0B, 0x00]
    assert [p[1][IvtMux.WH].counter for p in periods[1:17]] == trace_wh


def test_a_20_ms_result_advances_its_counter_by_1():
    sim = IvtSSimulator(period=0.02)
    periods = run(sim, IvtSCodec(), 0.4, step=0.02)
    assert [p[1][IvtMux.I].counter for p in periods[14:18]] == [14, 15, 0, 1]


def test_the_device_finds_the_simulated_counters_healthy():
    sim = IvtSSimulator()
    for command in ('34 00 01', '26 02 03 E8', '34 01 01'):  # stop, As cyclic 1000 ms, run
        sim.on_frame(Frame(0x411, bytes.fromhex(command).ljust(8, b'\0'), False), 0.0)
    assert sim.configs[IvtMux.AS].cycle_ms == 1000
    now = [0.0]
    device = IvtSDevice('ivt_s', {}, clock=lambda: now[0])
    for n in range(201):  # 20 s: As every second (+50 = +2 on the 4-bit counter)
        now[0] = n * 0.1
        for frame in sim.tick(now[0]):
            device.handle_frame(frame.arbitration_id, frame.data, now[0])
    values = device.diagnostic_report().values
    assert [values[f'{name} counter jumps'] for name in ('I', 'T', 'As')] == ['0'] * 3
    assert values['As counter step'] == '2' and values['I counter step'] == '5'


@pytest.mark.parametrize('order', ['big', 'little'])
def test_physics_is_consistent_in_both_byte_orders(order):
    sim = IvtSSimulator(byte_order=order)  # default drive profile, default sagging voltage
    codec = IvtSCodec(byte_order=order)
    periods = run(sim, codec, 20.0)
    charge = energy = 0.0
    for (prev_t, _), (now, results) in zip(periods, periods[1:]):
        current = results[IvtMux.I].value
        voltage = results[IvtMux.U1].value
        assert 380.0 < voltage < 402.0  # ~400 V with sag under load
        assert voltage == pytest.approx(400.0 - 0.05 * current, abs=0.002)
        # W is an integer on the wire: P = U * I within a watt.
        assert results[IvtMux.W].value == pytest.approx(voltage * current, abs=1.0)
        charge += current * (now - prev_t)
        energy += voltage * current * (now - prev_t) / 3600.0
        assert results[IvtMux.AS].value == pytest.approx(charge, abs=1.0)
        assert results[IvtMux.WH].value == pytest.approx(energy, abs=1.0)
        assert 20.0 < results[IvtMux.T].value < 60.0
    assert charge > 500.0  # a 20 s lap discharges: the integral really moved


def test_wrong_byte_order_does_not_read_the_same():
    sim = IvtSSimulator(byte_order='little', current_fn=lambda t: 12.5)
    frame = sim.tick(0.0)[0]
    assert IvtSCodec(byte_order='little').decode(frame.arbitration_id, frame.data).value == 12.5
    assert IvtSCodec(byte_order='big').decode(frame.arbitration_id, frame.data).value != 12.5


@pytest.mark.parametrize('discharge_positive', [True, False])
def test_wire_sign_follows_mounting_and_device_undoes_it(discharge_positive):
    sim = IvtSSimulator(discharge_positive=discharge_positive, current_fn=lambda t: 50.0,
                        voltage_fn=lambda: 380.0)
    codec = IvtSCodec()
    clock = [0.0]
    signs_checked = 0
    device = IvtSDevice('ivt_s', {'discharge_positive': discharge_positive},
                        clock=lambda: clock[0])
    for n in range(11):
        clock[0] = n * 0.1
        for frame in sim.tick(clock[0]):
            device.handle_frame(frame.arbitration_id, frame.data, clock[0])
            last = codec.decode(frame.arbitration_id, frame.data)
            if last.kind in (IvtMux.I, IvtMux.W, IvtMux.AS) and last.raw != 0:
                assert (last.value > 0) == discharge_positive
                signs_checked += 1
    assert signs_checked == 3 * 11 - 1  # only the first As (nothing integrated yet) is 0
    assert device.current_a() == pytest.approx(-50.0)  # ROS: negative while discharging
    assert device.voltage_v() == pytest.approx(380.0)
    assert device.charge_ah() == pytest.approx(-50.0 * 1.0 / 3600.0, abs=1 / 3600)


def test_faults_status_bits_and_stuck_counter():
    sim = IvtSSimulator()
    codec = IvtSCodec()
    sim.faults.error_code = 1
    sim.faults.extra['ocs'] = True
    results = [codec.decode(f.arbitration_id, f.data) for f in sim.tick(0.0)]
    assert all(r.system_error and r.ocs for r in results)
    assert not any(r.result_error or r.measurement_error for r in results)
    sim.faults.error_code = None
    sim.faults.extra = {'stuck_counter': True, 'measurement_error': True}
    first = [codec.decode(f.arbitration_id, f.data) for f in sim.tick(0.1)]
    second = [codec.decode(f.arbitration_id, f.data) for f in sim.tick(0.2)]
    assert [r.counter for r in first] == [r.counter for r in second]
    assert all(r.measurement_error and not r.system_error for r in second)


def test_silent_and_malformed_faults():
    sim = IvtSSimulator()
    codec = IvtSCodec()
    sim.faults.silent = True
    assert sim.tick(0.0) == []
    sim.faults.silent = False
    sim.faults.malformed = True
    frames = sim.tick(0.1)
    assert len(frames) == 8
    for frame in frames:
        with pytest.raises(MalformedFrameError, match='DLC 5'):
            codec.decode(frame.arbitration_id, frame.data)


def test_frames_cross_a_real_python_can_virtual_bus():
    channel = f'ivt_s_test_{time.monotonic_ns()}'
    sim = IvtSSimulator(byte_order='little', base_id=0x600, current_fn=lambda t: -20.0)
    device = IvtSDevice('ivt_s', {'byte_order': 'little', 'base_id': 0x600})
    with can.Bus(interface='virtual', channel=channel) as tx, \
            can.Bus(interface='virtual', channel=channel) as rx:
        for frame in sim.tick(0.0):
            tx.send(can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                                is_extended_id=frame.is_extended_id))
        for _ in range(8):
            msg = rx.recv(timeout=5.0)
            assert msg is not None
            assert msg.arbitration_id in device.arbitration_ids
            device.handle_frame(msg.arbitration_id, msg.data, msg.timestamp)
    assert device.frames_received == 8 and device.frames_malformed == 0
    assert device.current_a() == pytest.approx(20.0)  # charging: positive in ROS
    assert not math.isnan(device.voltage_v())


def test_error_queries_answer_the_item_asked():
    """0x40 / 0x41 b1 is the item (IVT-DBC _40_/_41_*_Item); the answer 0x80 / 0x81 echoes it."""
    sim = IvtSSimulator()
    sim.faults.error_code = 1
    sim.on_frame(Frame(0x411, bytes([0x41, 0x05, 0, 0, 0, 0, 0, 0])), 0.0)
    sim.on_frame(Frame(0x411, bytes([0x40, 0x07, 0, 0, 0, 0, 0, 0])), 0.0)
    answers = [decode_answer(f.data) for f in sim.tick(0.0) if f.arbitration_id == 0x511]
    assert answers == [ErrorAnswer(True, 5, 1), ErrorAnswer(False, 7, 0)]


def test_reset_is_answered_in_run_but_carried_out_only_in_stop():
    """
    The datasheet: 0x30 only in Stop mode; every defined command is answered anyway.

    Frames by hand: 30 01 00 | 00 01 23 45 (all system errors, serial 74565); answer B0 with
    the same item and serial; 34 00 01 = STOP now, RUN after power-up.
    """
    sim = IvtSSimulator()
    sim.faults.error_code = 1
    reset = Frame(0x411, bytes([0x30, 0x01, 0x00, 0x00, 0x01, 0x23, 0x45, 0]))
    sim.on_frame(reset, 0.0)
    answers = [f.data for f in sim.tick(0.0) if f.arbitration_id == 0x511]
    assert answers == [bytes([0xB0, 0x01, 0x00, 0x00, 0x01, 0x23, 0x45, 0])]
    assert sim.faults.error_code == 1  # running: nothing reset
    sim.on_frame(Frame(0x411, bytes([0x34, 0x00, 0x01, 0, 0, 0, 0, 0])), 0.1)
    sim.on_frame(reset, 0.1)
    answers = [f.data for f in sim.tick(0.1) if f.arbitration_id == 0x511]
    assert answers[-1] == bytes([0xB0, 0x01, 0x00, 0x00, 0x01, 0x23, 0x45, 0])
    assert sim.faults.error_code is None
