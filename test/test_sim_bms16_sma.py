# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""BMS16 and SMA simulators: schedules, physics, config and commands, faults, on a real bus."""
import time

import can
import pytest

from ams_can_bridge.devices.base import Level, PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.devices.bms16.inverter import Bms16Device
from ams_can_bridge.devices.sma.device import SmaDevice
from ams_can_bridge.protocols.bms16 import (
    AcknowledgeError, Bms16Codec, Bms16Settings, Bms16ConfigPart1, Bms16ConfigPart2, Bms16Error,
    PowerOff, ResetSoc)
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.sma import SmaCodec, SmaFlag
from ams_can_bridge.sim.bms16 import Bms16Simulator
from ams_can_bridge.sim.sma import SmaSimulator
from helpers import run_sim

CONFIG = Bms16Settings(cells=12, pack_capacity_ah=50, soc_warning_pct=20, full_voltage_v=43,
                       warn_current_a=200, trip_current_a=300, temperature_limit_c=60,
                       min_cell_v=2.8, max_cell_v=3.65, hysteresis_v=0.1, balance_v=3.45,
                       shunt_size_a=200)


def count(frames, frame_id):
    return sum(1 for f in frames if f.arbitration_id == frame_id)


def test_bms16_sends_status_cells_and_sma_at_4_hz():
    frames = run_sim(Bms16Simulator(), None, 10.0)
    for frame_id in (500, 501, 502, 503, 0x351, 0x355, 0x356, 0x35A):
        assert count(frames, frame_id) == 40
    bms16, sma = Bms16Codec(), SmaCodec()
    for frame in frames:  # every frame the simulator sends is valid
        codec = bms16 if frame.arbitration_id < 0x351 or frame.arbitration_id > 0x35F else sma
        codec.decode(frame.arbitration_id, frame.data)


def test_bms16_soc_follows_the_current_with_both_wire_signs():
    sim = Bms16Simulator(current_fn=lambda t: 50.0, capacity_ah=10.0)
    device = Bms16Device('bms16', {'config.pack_capacity_ah': 10.0})
    frames = run_sim(sim, device, 36.0)
    assert sim.soc_pct == pytest.approx(75.0, abs=0.1)  # 50 A x 36 s = 0.5 Ah of 10 Ah
    report = device.battery_report()
    assert report.percentage == 0.75
    assert report.current == -50.0
    assert report.power_supply_status == PowerSupplyStatus.DISCHARGING
    assert len(report.cell_voltage) == 16 and all(3.0 < v < 3.5 for v in report.cell_voltage)
    assert report.voltage == pytest.approx(sum(report.cell_voltage), abs=0.1)
    sma = [SmaCodec().decode(f.arbitration_id, f.data) for f in frames
           if f.arbitration_id == 0x356]
    assert sma[-1].current_a == -50.0  # SMA wire: positive = charging
    assert device.diagnostic_report().level == Level.OK


def test_bms16_stores_config_and_uses_it():
    sim = Bms16Simulator()
    codec = Bms16Codec()
    for frame in codec.config_frames(CONFIG):
        sim.on_frame(frame, 0.0)
    assert sim.config1 == Bms16ConfigPart1(12, 50.0, 20.0, 43.0, 200.0, 300.0, 60.0, 2.8)
    assert sim.config2 == Bms16ConfigPart2(3.65, 0.1, 3.45, 200)
    assert sim.cells == 12 and sim.capacity_ah == 50.0
    frames = sim.tick(0.0)
    cells3 = codec.decode(503, next(f.data for f in frames if f.arbitration_id == 503))
    assert cells3.voltages_v == (0.0,) * 4
    limits = SmaCodec().decode(0x351, next(f.data for f in frames if f.arbitration_id == 0x351))
    assert limits.charge_voltage_v == 43.0 and limits.discharge_voltage_v == 33.6


def test_bms16_restricts_received_config_like_the_device():
    sim = Bms16Simulator()
    sim.on_frame(Frame(504, bytes([40, 0, 200, 150, 255, 255, 255, 0])), 0.0)
    assert sim.config1 == Bms16ConfigPart1(16, 10.0, 100.0, 100.0, 1000.0, 1000.0, 100.0, 1.0)
    sim.on_frame(Frame(505, bytes([73, 2, 69, 7])), 0.0)  # shunt code 7: unreadable
    assert sim.config2 is None


def test_bms16_error_ack_reset_soc_and_power_off():
    sim = Bms16Simulator(current_fn=lambda t: 0.0)
    device = Bms16Device('bms16', {})
    sim.faults.error_code = 3
    run_sim(sim, device, 0.5)
    assert device.error == Bms16Error.CHARGE_DISABLED_OVERVOLTAGE
    assert device.battery_report().power_supply_health == PowerSupplyHealth.OVERVOLTAGE
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR and diag.values['sma alarm high_voltage'] == 'ACTIVE'
    codec = Bms16Codec()
    sim.on_frame(codec.encode(AcknowledgeError()), 0.5)
    sim.on_frame(codec.encode(ResetSoc()), 0.5)
    run_sim(sim, device, 0.5, start=0.5)
    assert device.error == Bms16Error.NONE and device.battery_report().percentage == 1.0
    sim.on_frame(codec.encode(PowerOff()), 1.0)
    assert run_sim(sim, None, 2.0, start=1.0) == []
    sim.power_on()
    assert sim.tick(3.0)


def test_bms16_low_soc_warning_from_config():
    sim = Bms16Simulator(current_fn=lambda t: 0.0)
    for frame in Bms16Codec().config_frames(CONFIG):
        sim.on_frame(frame, 0.0)
    sim.soc_pct = 15.0
    device = Bms16Device('bms16', {})
    run_sim(sim, device, 0.3)
    assert device.error == Bms16Error.LOW_SOC
    assert device.diagnostic_report().level == Level.WARN


def test_bms16_faults_silent_malformed_drift():
    sim = Bms16Simulator(current_fn=lambda t: 0.0)
    sim.faults.silent = True
    assert run_sim(sim, None, 1.0) == []
    sim.faults.silent = False
    sim.faults.malformed = True
    device = Bms16Device('bms16', {})
    frames = run_sim(sim, device, 1.0, start=1.0)
    assert frames and device.frames_received == 0
    assert device.frames_malformed == len(frames)
    sim.faults.malformed = False
    sim.faults.cell_drift_v = 0.3
    sim.faults.drift_cell = 5
    run_sim(sim, device, 0.3, start=2.0)
    cells = device.battery_report().cell_voltage
    assert cells[5] - max(cells[:5] + cells[6:]) > 0.25


def test_simulators_are_deterministic():
    def frames(sim):
        return run_sim(sim, None, 5.0)
    assert frames(Bms16Simulator(seed=3)) == frames(Bms16Simulator(seed=3))
    assert frames(Bms16Simulator(seed=3)) != frames(Bms16Simulator(seed=4))
    assert frames(SmaSimulator(seed=1)) == frames(SmaSimulator(seed=1))


def test_bms16_without_sma_frames_and_other_base_id():
    frames = run_sim(Bms16Simulator(base_id=0x100, send_sma=False), None, 1.0)
    assert {f.arbitration_id for f in frames} == {0x100, 0x101, 0x102, 0x103}


def test_sma_periods():
    frames = run_sim(SmaSimulator(), None, 10.0)
    for frame_id in (0x351, 0x355, 0x356, 0x35A):
        assert count(frames, frame_id) == 10
    assert count(frames, 0x35E) == 2 and count(frames, 0x35F) == 2


def test_sma_soc_sign_and_info_reach_the_device():
    sim = SmaSimulator(current_fn=lambda t: 50.0, capacity_ah=10.0, manufacturer='ACME')
    device = SmaDevice('sma', {})
    run_sim(sim, device, 37.0)
    report = device.battery_report()
    assert report.percentage == pytest.approx(0.75, abs=0.002)
    assert report.current == -50.0
    assert report.power_supply_status == PowerSupplyStatus.DISCHARGING
    assert report.capacity == 10.0 and 48.0 < report.voltage < 56.0
    assert report.power_supply_health == PowerSupplyHealth.GOOD
    values = device.diagnostic_report().values
    assert values['manufacturer'] == 'ACME' and values['soh %'] == '100'
    assert values['alarm contactor'] == 'NOT_SUPPORTED' and values['alarm general'] == 'OK'
    sim.current_fn = lambda t: -20.0
    run_sim(sim, device, 1.0, start=37.0)
    assert device.battery_report().current == 20.0


def test_sma_faults_alarm_warning_drift_malformed_silent():
    sim = SmaSimulator()
    device = SmaDevice('sma', {})
    sim.faults.extra['alarm'] = 'low_temperature'
    sim.faults.extra['warning'] = ['high_charge_current']
    run_sim(sim, device, 1.0)
    assert device.battery_report().power_supply_health == PowerSupplyHealth.COLD
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert diag.values['warnings active'] == 'high_charge_current'
    sim.faults.extra.clear()
    sim.faults.cell_drift_v = 0.08
    run_sim(sim, device, 1.0, start=1.0)
    assert device.diagnostic_report().values['warnings active'] == 'cell_imbalance'
    assert sim.alarms().warnings['cell_imbalance'] is SmaFlag.ACTIVE
    sim.faults.malformed = True
    malformed_before = device.frames_malformed
    frames = run_sim(sim, device, 1.0, start=2.0)
    assert device.frames_malformed - malformed_before == len(frames) > 0
    sim.faults.malformed = False
    sim.faults.silent = True
    assert run_sim(sim, device, 5.0, start=3.0) == []
    sim.faults.extra['alarm'] = 'overvoltage'
    with pytest.raises(ValueError, match='unknown SMA condition'):
        sim.alarms()


def test_simulated_frames_cross_a_python_can_bus():
    sim = Bms16Simulator(current_fn=lambda t: 10.0)
    device = Bms16Device('bms16', {'config.cells': 16})
    channel = f'bms16-{time.monotonic_ns()}'
    with can.Bus(interface='virtual', channel=channel) as tx, \
            can.Bus(interface='virtual', channel=channel) as rx:
        sent = sim.tick(0.0)
        for frame in sent:
            tx.send(can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                                is_extended_id=frame.is_extended_id))
        received = 0
        deadline = time.monotonic() + 5.0
        while received < len(sent) and time.monotonic() < deadline:
            msg = rx.recv(timeout=0.5)
            if msg is not None:
                received += 1
                device.handle_frame(msg.arbitration_id, bytes(msg.data), msg.timestamp)
    assert received == len(sent) == 8
    report = device.battery_report()
    assert report.present and report.current == -10.0
    assert not any(v != v for v in report.cell_voltage)
