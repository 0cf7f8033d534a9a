# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The standard-form BMS16 simulator (``simulator --bms16-variant standard``) and the bridge."""
import math

from ams_can_bridge import registry
from ams_can_bridge.devices.base import device_params
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.sim.bms16_std import Bms16StdSimulator
from ams_can_bridge.sim.main import build_devices, build_parser
from helpers import Clock
from shared import BMS16_STD_CONFIG as CONFIG, BMS16_STD_WRITE as GOLDEN_WRITE


def test_cli_option_selects_the_standard_form():
    args = build_parser().parse_args(['--devices', 'bms16', '--bms16-variant', 'standard'])
    (sim,) = build_devices(args.devices, bms16_variant=args.bms16_variant)
    assert isinstance(sim, Bms16StdSimulator)
    assert type(build_devices(['bms16'])[0]).__name__ == 'Bms16Simulator'  # default: inverter


def test_bridge_device_reads_what_the_simulator_sends():
    sim = Bms16StdSimulator(cells=12, capacity_ah=100.0, current_fn=lambda now: 20.0)
    frames = sim.tick(0.0)
    assert {f.arbitration_id for f in frames} == {30, 301, 302, 311, 40}  # 12 cells: 8 + 4
    assert all(f.is_extended_id for f in frames)
    cls = registry.device_class('bms16', 'standard')
    values = {s.key: s.default for s in device_params(cls)}
    values.update({'config.cells': 12, 'config.pack_capacity_ah': 100})
    device = cls('bms16', values, Clock())
    for f in frames:
        device.handle_frame(f.arbitration_id, f.data, 0.0)
    report = device.battery_report()
    assert report.present and report.current == -20.0
    assert report.percentage == 0.8 and len(report.cell_voltage) == 12
    assert not any(math.isnan(v) for v in report.cell_voltage)
    assert report.voltage == round(sum(sim.cell_voltages()), 1)


def test_simulator_takes_the_monitors_settings_and_commands():
    sim = Bms16StdSimulator()
    for can_id, data in GOLDEN_WRITE:  # written by hand from the Monitor firmware
        sim.on_frame(Frame(can_id, data, True), 0.0)
    assert sim.config['cells'] == 14 and sim.cells == 14
    assert sim.config['full_voltage_v'] == 58 and sim.config['shunt_size_a'] == 200
    assert sim.config['balance_v'] == CONFIG['balance_v'] and sim.capacity_ah == 200
    sim.faults.error_code = 10
    sim.on_frame(Frame(37, b'\x0a', True), 0.0)
    assert sim.faults.error_code is None
    sim.soc_pct = 50.0
    sim.on_frame(Frame(38, b'', True), 0.0)
    assert sim.soc_pct == 100.0
    sim.on_frame(Frame(39, b'', True), 0.0)
    assert sim.tick(1.0) == [] and not sim.powered
