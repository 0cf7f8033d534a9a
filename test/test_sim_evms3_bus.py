# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Simulated EVMS3 bus: charging with TC chargers that answer, and the answer to ID 51."""
import pytest

from ams_can_bridge.devices.base import Level, PowerSupplyStatus
from ams_can_bridge.devices.evms3.device import Evms3Device
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import (
    Bms12Request, ConfigReadback, ConfigReport, Evms3Codec, Evms3Settings, Evms3State,
    Evms3Status, RequestConfig)
from ams_can_bridge.protocols.tc_charger import ChargerCommand, ChargerStatus
from ams_can_bridge.sim.evms3 import Evms3Simulator
from ams_can_bridge.sim.main import build_devices, build_parser

CODEC = Evms3Codec()


def run(sim, start, stop, device=None, step=0.01):
    out = []
    for i in range(int(round((stop - start) / step)) + 1):
        now = start + i * step
        for frame in sim.tick(now):
            out.append(CODEC.decode(frame.arbitration_id, frame.data))
            if device is not None:
                device.handle_frame(frame.arbitration_id, frame.data, now)
    return out


def of(readings, kind):
    return [r for r in readings if isinstance(r, kind)]


def test_no_charger_traffic_while_driving():
    readings = run(Evms3Simulator(bms12_modules=1), 0.0, 3.0)
    assert not of(readings, ChargerCommand) and not of(readings, ChargerStatus)


def test_charging_phase_commands_and_answers_once_a_second():
    sim = Evms3Simulator(bms12_modules=2, chargers=2, charge_after_s=1.0, capacity_ah=50.0)
    sim.remaining_ah = 25.0  # half full: far below the target, the full current flows
    readings = run(sim, 0.0, 6.0)
    assert of(readings, Evms3Status)[-1].state is Evms3State.CHARGING
    commands, answers = of(readings, ChargerCommand), of(readings, ChargerStatus)
    assert 8 <= len(commands) <= 10 and 8 <= len(answers) <= 10  # 2 chargers, ~1 Hz
    assert {c.charger for c in commands} == {1, 2} == {a.charger for a in answers}
    # no config written: the pack's own, 24 cells x 4.15 V in whole volts (100 V), 10 A
    # shared by the two chargers
    assert commands[-1] == ChargerCommand(2, 100.0, 5.0, False)
    assert answers[-1].output_current_a == 5.0 and answers[-1].status == 0
    assert answers[-1].output_voltage_v == pytest.approx(of(readings, Evms3Status)[-1]
                                                         .pack_voltage_v, abs=0.3)
    assert sim.current_a == -10.0  # wire sign: charging is negative


def test_charging_fills_the_pack_then_the_evms_stops_the_chargers():
    sim = Evms3Simulator(bms12_modules=1, charge_after_s=0.0, capacity_ah=0.01)
    sim.remaining_ah = 0.005  # 18 A s to go: about 2 s at 10 A, then the taper
    readings = run(sim, 0.0, 12.0)
    commands = of(readings, ChargerCommand)
    answers = of(readings, ChargerStatus)
    assert not commands[0].stop and commands[-1].stop
    assert answers[0].output_current_a == 10.0 and answers[-1].output_current_a == 0.0
    assert sim.soc > 0.95 and sim.current_a == 0.0
    stopped = [c.stop for c in commands]
    assert stopped == sorted(stopped)  # once stopped, it stays stopped


def test_stored_config_sets_target_and_balancing():
    sim = Evms3Simulator(bms12_modules=1, charge_after_s=0.0)
    cfg = Evms3Settings(
        pack_capacity_ah=100, soc_warning_pct=20, full_voltage_v=50, warn_current_a=100,
        trip_current_a=200, temp_warning_c=60, min_aux_voltage_v=11, min_isolation_pct=50,
        tacho_ppr=2, fuel_gauge_full_pct=90, fuel_gauge_empty_pct=10, temp_gauge_hot_pct=80,
        temp_gauge_cold_pct=20, bms_min_cell_v=3.0, bms_max_cell_v=4.2, balance_v=None,
        balance_mode='dynamic', bms_hysteresis_v=0.05, bms_min_temp_c=0, bms_max_temp_c=55,
        max_charge_voltage_v=49, max_charge_current_a=16, alt_charge_voltage_v=45,
        alt_charge_current_a=8, sleep_delay_min=3, mpi_function=0, mpo1_function=0,
        mpo2_function=0, parallel_strings=1, enable_precharge=True, stationary_mode=False,
        reverse_current_display=False, night_brightness=10)
    for frame in CODEC.config_frames(cfg):
        sim.on_frame(frame, 0.0)
    readings = run(sim, 0.0, 2.0)
    assert of(readings, ChargerCommand)[-1] == ChargerCommand(1, 49.0, 16.0, False)
    lowest = min(sim.cell_voltages()[0])
    assert of(readings, Bms12Request)[-1].balance_mv == pytest.approx(lowest * 1000, abs=2)


def test_charger_fault_reaches_the_device_as_warn():
    sim = Evms3Simulator(bms12_modules=1, charge_after_s=0.0)
    device = Evms3Device('evms3', {'bms12_modules': 1}, clock=lambda: 0.0)
    sim.faults.extra['charger_status'] = 0b0000_0100  # input (AC) voltage error
    run(sim, 0.0, 2.0, device)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'charger 1: input (AC) voltage error' in diag.message
    assert diag.values['charger 1 output amps (A)'] == '0.0'  # a faulted charger delivers 0
    assert diag.values['module 0 balance target (mV)'] != 'off'  # dynamic while charging
    assert device.battery_report().power_supply_status == PowerSupplyStatus.CHARGING


def test_command_line_options():
    args = build_parser().parse_args(['--devices', 'evms3', '--evms3-charge-after', '5',
                                      '--evms3-chargers', '3'])
    [sim] = build_devices(args.devices, evms3_charge_after=args.evms3_charge_after,
                          evms3_chargers=args.evms3_chargers)
    assert (sim.charge_after_s, sim.chargers) == (5.0, 3)
    with pytest.raises(ValueError, match='0..3'):
        Evms3Simulator(chargers=4)


def test_answers_51_with_its_configuration_on_52_to_56():
    sim = Evms3Simulator(bms12_modules=3, cells_per_module=[12, 12, 10])
    assert not any(isinstance(r, ConfigReport) for r in run(sim, 0.0, 1.0))  # unasked
    sim.on_frame(Frame(51, b'\x07', True), 1.0)  # any data: the firmware does not look
    readings = run(sim, 1.01, 1.02)
    reports = of(readings, ConfigReport)
    assert [r.arbitration_id for r in reports] == [52, 53, 54, 55, 56]
    readback = ConfigReadback.join(reports)
    assert readback.config.balance_mode == 'dynamic'  # firmware default, never configured
    assert readback.cells_per_module == (12, 12, 10) + (0,) * 13
    assert sim.received == [RequestConfig()]
    assert not of(run(sim, 1.03, 2.0), ConfigReport)  # one answer per request
    sim.on_frame(Frame(51, b'', False), 2.0)  # an 11-bit 51 is not for this EVMS3
    sim.faults.extra['config_answer'] = [53]
    sim.on_frame(Frame(51, b'', True), 2.0)
    assert [r.arbitration_id for r in of(run(sim, 2.01, 2.02), ConfigReport)] == [53]
