# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Simulated EVMS3 + BMS12: rates, physics, reactions to commands, faults, and a real bus."""
import dataclasses
import math
import uuid

import can
import pytest

from ams_can_bridge.devices.evms3.device import Evms3Device
from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import (
    AcknowledgeError, BatteryCurrent, Bms12Cells, Bms12Request,
    BmsCellNumbers, Evms3Codec, Evms3Settings, Evms3Error, Evms3State, Evms3Status, PowerOff,
    ConfigReadback, ResetSoc, SetState)
from ams_can_bridge.sim.evms3 import Evms3Simulator

CODEC = Evms3Codec()
CONFIG = Evms3Settings(
    pack_capacity_ah=60, soc_warning_pct=20, full_voltage_v=100, warn_current_a=300,
    trip_current_a=500, temp_warning_c=60, min_aux_voltage_v=11, min_isolation_pct=50,
    tacho_ppr=2, fuel_gauge_full_pct=90, fuel_gauge_empty_pct=10, temp_gauge_hot_pct=80,
    temp_gauge_cold_pct=20, bms_min_cell_v=3.0, bms_max_cell_v=4.2, balance_v=4.1,
    balance_mode='static', bms_hysteresis_v=0.05, bms_min_temp_c=0, bms_max_temp_c=55,
    max_charge_voltage_v=300, max_charge_current_a=30, alt_charge_voltage_v=250,
    alt_charge_current_a=10, sleep_delay_min=3, mpi_function=1, mpo1_function=2,
    mpo2_function=6, parallel_strings=1, enable_precharge=True, stationary_mode=False,
    reverse_current_display=False, night_brightness=10)


def run(sim, start, stop, step=0.01):
    """Tick from start to stop; return the decoded readings."""
    out = []
    n = int(round((stop - start) / step))
    for i in range(n + 1):
        out += [CODEC.decode(f.arbitration_id, f.data) for f in sim.tick(start + i * step)]
    return out


def last(readings, kind):
    return [r for r in readings if isinstance(r, kind)][-1]


def send(sim, msg, now=0.0):
    sim.on_frame(CODEC.encode(msg), now)


def test_frames_and_rates():
    sim = Evms3Simulator(bms12_modules=2)
    frames = []
    for i in range(200):  # 2 s
        frames += sim.tick(i * 0.01)
    assert all(f.is_extended_id for f in frames)
    ids = [f.arbitration_id for f in frames]
    assert 7 <= ids.count(30) <= 9  # 4 Hz
    assert 18 <= ids.count(40) <= 21  # 10 Hz
    for module_base in (300, 310):
        for t in range(5):
            assert 3 <= ids.count(module_base + t) <= 5  # every 0.5 s
    assert not any(320 <= aid < 460 for aid in ids)


def test_running_by_default_pack_voltage_is_the_sum_of_the_cells():
    sim = Evms3Simulator(bms12_modules=3, cells_per_module=10,
                         current_fn=lambda t: 0.0, seed=3)
    readings = run(sim, 0.0, 1.0)
    status = last(readings, Evms3Status)
    assert status.state is Evms3State.RUNNING and status.error is Evms3Error.NONE
    cells = [r for r in readings if isinstance(r, Bms12Cells)][-9:]
    voltages = [v for r in cells for v in r.voltages_v[:10 - r.first_cell]]
    assert len(voltages) == 30
    assert all(v == 0.0 for r in cells if r.first_cell == 8 for v in r.voltages_v[2:])
    assert status.pack_voltage_v == pytest.approx(sum(voltages), abs=0.051)
    assert last(readings, Bms12Request).balance_mv is None  # no config: no balancing


def test_current_sign_and_amp_hours():
    sim = Evms3Simulator(current_fn=lambda t: 36.0, capacity_ah=100.0)
    readings = run(sim, 0.0, 10.0)
    assert last(readings, BatteryCurrent).current_a == 36.0  # wire: positive = discharge
    # 36 A for 10 s = 0.1 Ah out of 90 Ah
    assert last(readings, Evms3Status).amp_hours_ah == pytest.approx(89.9, abs=0.11)
    charging = Evms3Simulator(current_fn=lambda t: -18.0)
    readings = run(charging, 0.0, 10.0)
    assert last(readings, BatteryCurrent).current_a == -18.0
    assert charging.remaining_ah == pytest.approx(90.05, abs=0.001)


def test_config_goes_to_ram_and_is_saved_only_on_35():
    # EVMS3 firmware: 32..35 write settings[] (RAM) at once; only 35 sets saveToEepromFlag
    sim = Evms3Simulator()
    frames = CODEC.config_frames(CONFIG)
    for f in (frames[2], frames[0], frames[1]):
        sim.on_frame(f, 0.0)
        assert sim.stored_config is None and sim.eeprom_writes == 0
    assert sim.ram_config.pack_capacity_ah == 60  # in use at once
    sim.on_frame(frames[3], 0.0)
    assert sim.stored_config == CONFIG and sim.eeprom_writes == 1
    assert sim.capacity_ah == 60.0
    # one packet of a new configuration changes RAM, not EEPROM
    sim.on_frame(CODEC.config_frames(dataclasses.replace(CONFIG, pack_capacity_ah=70))[0], 1.0)
    assert sim.stored_config == CONFIG and sim.ram_config.pack_capacity_ah == 70
    readings = run(sim, 1.0, 2.0)
    assert last(readings, Bms12Request).balance_mv == 4100  # static balance from the config
    sim.power_cycle()
    assert sim.ram_config == CONFIG


@pytest.mark.parametrize('order,kept', [
    ((36, 32, 33, 34, 35), True),   # the Monitor's order (TransmitSettings)
    ((32, 33, 34, 35, 36), False),  # 36 after the save on 35: RAM only, lost at power-up
])
def test_cell_counts_survive_a_power_cycle_only_before_35(order, kept):
    sim = Evms3Simulator(state=Evms3State.IDLE)
    cells = (12, 10) + (0,) * 14
    frames = {f.arbitration_id: f for f in CODEC.config_frames(CONFIG)}
    frames[36] = CODEC.encode(BmsCellNumbers(cells))
    for can_id in order:
        sim.on_frame(frames[can_id], 0.0)
    assert sim.cell_numbers == cells  # RAM: looks written either way
    sim.power_cycle()
    assert (sim.cell_numbers == cells) is kept
    answer = ConfigReadback.join(CODEC.decode(f.arbitration_id, f.data)
                                 for f in sim.config_answer())
    assert (answer.cells_per_module == cells) is kept


def test_reset_soc_and_cell_numbers():
    sim = Evms3Simulator(current_fn=lambda t: 360.0)
    run(sim, 0.0, 10.0)
    assert sim.remaining_ah == pytest.approx(89.0, abs=0.01)
    send(sim, ResetSoc(), 10.0)
    assert last(run(sim, 10.0, 10.3), Evms3Status).amp_hours_ah == pytest.approx(100.0, abs=0.1)
    send(sim, BmsCellNumbers((12, 10) + (0,) * 14))
    assert sim.cell_numbers == (12, 10) + (0,) * 14


def test_set_state_and_acknowledge_error():
    sim = Evms3Simulator()
    sim.faults.error_code = 12
    assert last(run(sim, 0.0, 0.3), Evms3Status).error is Evms3Error.ISOLATION_ERROR
    send(sim, AcknowledgeError(Evms3Error.LOW_12V))  # not the reported one: no effect
    assert last(run(sim, 0.3, 0.6), Evms3Status).error is Evms3Error.ISOLATION_ERROR
    send(sim, AcknowledgeError(Evms3Error.ISOLATION_ERROR))
    assert last(run(sim, 0.6, 0.9), Evms3Status).error is Evms3Error.NONE
    send(sim, SetState(True))  # RUNNING: the firmware enters Setup only from IDLE
    assert last(run(sim, 0.9, 1.2), Evms3Status).state is Evms3State.RUNNING
    sim.state = Evms3State.IDLE  # key off: the request still pending takes it to Setup
    readings = run(sim, 1.2, 1.5)
    assert last(readings, Evms3Status).state is Evms3State.SETUP
    assert last(readings, BatteryCurrent).current_a == 0.0
    send(sim, SetState(True, 2, 80))  # the Monitor editing the fuel gauge: stays in Setup
    assert last(run(sim, 1.5, 1.8), Evms3Status).state is Evms3State.SETUP
    send(sim, SetState(False))
    assert last(run(sim, 1.8, 2.1), Evms3Status).state is Evms3State.IDLE
    assert len(sim.received) == 5


def test_power_off_and_bad_commands():
    sim = Evms3Simulator()
    sim.on_frame(Frame(31, b'\x07', True), 0.0)  # set state 7: malformed, ignored
    sim.on_frame(Frame(31, b'\x01', False), 0.0)  # 11-bit ID 31: not the EVMS
    assert sim.malformed_received == 1 and sim.state is Evms3State.RUNNING
    send(sim, PowerOff())
    assert run(sim, 0.0, 1.0) == []
    sim.power_on()
    assert run(sim, 1.0, 1.5)


def test_faults_silent_malformed_drift():
    sim = Evms3Simulator()
    sim.faults.silent = True
    assert run(sim, 0.0, 1.0) == []
    sim.faults.silent = False
    sim.faults.malformed = True
    frames = [f for i in range(100) for f in sim.tick(1.0 + i * 0.01)]
    assert frames
    for f in frames:
        with pytest.raises(MalformedFrameError):
            CODEC.decode(f.arbitration_id, f.data)
    sim.faults.malformed = False
    sim.faults.cell_drift_v = 0.5
    sim.faults.drift_cell = 13  # module 1, cell 2
    cells = sim.cell_voltages()
    others = cells[1][:1] + cells[1][2:]
    assert cells[1][1] > max(others) + 0.4


def test_deterministic():
    a, b = Evms3Simulator(seed=7), Evms3Simulator(seed=7)
    frames_a = [f for i in range(100) for f in a.tick(i * 0.01)]
    frames_b = [f for i in range(100) for f in b.tick(i * 0.01)]
    assert frames_a == frames_b
    c = Evms3Simulator(seed=8)
    assert [f for i in range(100) for f in c.tick(i * 0.01)] != frames_a


def test_over_a_real_python_can_bus_into_the_device():
    channel = f'evms3-{uuid.uuid4()}'
    sim_bus = can.Bus(interface='virtual', channel=channel)
    bridge_bus = can.Bus(interface='virtual', channel=channel)
    try:
        sim = Evms3Simulator(bms12_modules=2, current_fn=lambda t: 25.0)
        device = Evms3Device('evms3', {'bms12_modules': 2, 'config.pack_capacity_ah': 100})
        for i in range(60):
            for f in sim.tick(i * 0.01):
                sim_bus.send(can.Message(arbitration_id=f.arbitration_id, data=f.data,
                                         is_extended_id=f.is_extended_id))
        # a marker after the simulator's frames: read up to it, not until 0.5 s of silence
        sim_bus.send(can.Message(arbitration_id=0x7FF, data=b'', is_extended_id=False))
        bridge_bus.send(can.Message(arbitration_id=38, data=b'', is_extended_id=True))
        while True:
            msg = bridge_bus.recv(timeout=5.0)
            assert msg is not None, 'the marker did not arrive'
            if msg.arbitration_id == 0x7FF:
                break
            assert msg.is_extended_id
            device.handle_frame(msg.arbitration_id, bytes(msg.data), msg.timestamp)
        msg = sim_bus.recv(timeout=2.0)
        sim.on_frame(Frame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id), 0.6)
        assert sim.remaining_ah == 100.0
        report = device.battery_report()
        assert report.present and device.frames_malformed == 0
        assert report.current == -25.0
        assert report.percentage == pytest.approx(0.9, abs=0.001)
        assert len(report.cell_voltage) == 24
        assert all(3.9 < v < 4.3 for v in report.cell_voltage)
    finally:
        sim_bus.shutdown()
        bridge_bus.shutdown()


def test_device_fed_by_the_simulator_reports_a_plausible_pack():
    """Every simulated frame through a real Evms3Device (clock = simulated time)."""
    step_at = 10.0  # discharge 180 A, then charge 180 A (wire sign: + = discharge)
    sim = Evms3Simulator(bms12_modules=2, current_fn=lambda t: 180.0 if t < step_at else -180.0,
                         capacity_ah=100.0, seed=5)
    now = [0.0]
    device = Evms3Device('evms3', {'bms12_modules': 2, 'config.pack_capacity_ah': 100},
                         clock=lambda: now[0])
    reports = []  # (time, report) at every primary frame (ID 30), as the node publishes
    for i in range(2001):  # 20 s of simulated time
        now[0] = i * 0.01
        for f in sim.tick(now[0]):
            if device.handle_frame(f.arbitration_id, f.data, now[0]):
                reports.append((now[0], device.battery_report()))
    assert device.frames_malformed == 0
    # Once every BMS12 frame came round (0.5 s), each report has all 24 cells, no NaN, and
    # the pack voltage is their sum (0.1 V resolution on the wire) - except right after the
    # current step, while the cells (0.5 s period) still show the old current's IR drop.
    checked = [(t, r) for t, r in reports if t >= 0.6 and not step_at <= t < step_at + 0.6]
    assert len(checked) > 60
    for t, report in checked:
        assert report.present
        assert len(report.cell_voltage) == 24
        assert not any(math.isnan(v) for v in report.cell_voltage), t
        assert report.voltage == pytest.approx(sum(report.cell_voltage), abs=0.1), t
    # Charge and SoC follow the current: down while discharging, back up while charging.
    discharging = [r for t, r in checked if t < step_at]
    charging = [r for t, r in checked if t > step_at]
    assert all(r.current == -180.0 for r in discharging)
    assert all(r.current == 180.0 for r in charging)
    assert discharging[-1].charge < discharging[0].charge  # 180 A * ~9 s = 0.45 Ah out
    assert discharging[-1].percentage < discharging[0].percentage
    assert charging[-1].charge > charging[0].charge
    assert charging[-1].percentage > charging[0].percentage
    assert [r.charge for r in discharging] == sorted((r.charge for r in discharging),
                                                     reverse=True)
    assert [r.charge for r in charging] == sorted(r.charge for r in charging)
    assert charging[-1].percentage == pytest.approx(charging[-1].charge / 100.0)
