# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Missing data is never OK; a status a monitor can carry; a simulator that behaves like a BMS.

On foxBMS 2's own DBC (the shipped profile, 54 multiplexer values of cell voltages) and our
hand-written BMS: a group that has not arrived within its timeout since start, or expired,
makes the device WARN counting and naming what is missing; ``values: all`` is capped; the
simulator sends the DBC's own units and meaning, so a mapping that reads them wrong shows it.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import cantools
import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.devices.dbc.diagnostics import VALUES_CAP
from ams_can_bridge.protocols.dbc_profiles import profile_files
from ams_can_bridge.sim.dbc import DbcSimulator
from dbc_fixtures import FRAMES, OUR_MAPPING, write_files
from helpers import Clock


def foxbms(clock: Clock, mapping: str | None = None, tmp_path: Path | None = None) -> DbcDevice:
    params = {'profile': 'foxbms2', 'stale_timeout': 1.0}
    if mapping is not None and tmp_path is not None:
        (tmp_path / 'fox.yaml').write_text(mapping)
        params['mapping_file'] = str(tmp_path / 'fox.yaml')
    return DbcDevice('pack', params, clock)


def cells_frame(mux: int, mv: tuple[int, int, int, int], valid: int = 0xF) -> bytes:
    """Encode an f_CellVoltages frame by foxbms.dbc (cantools: the field tests are by hand)."""
    dbc, _ = profile_files('foxbms2')
    message = cantools.database.load_file(str(dbc)).get_message_by_frame_id(0x250)
    values = {'f_CellVoltages_Mux': mux}
    for k in range(4):
        cell = 4 * mux + k
        values[f'CellVoltage_{cell:03d}'] = mv[k]
        values[f'CellVoltage_{cell:03d}_invalidFlag'] = (valid >> k) & 1
    return message.encode(values)


# --- 6. missing data is never OK -------------------------------------------------------------
def test_cells_not_received_are_counted_and_named_by_multiplexer_value(tmp_path):
    clock = Clock(100.0)
    mapping = (profile_files('foxbms2')[1].read_text()
               .replace('count: 18', 'count: 16').replace('count: 8', 'count: 6'))
    device = foxbms(clock, mapping, tmp_path)
    device.handle_frame(0x250, cells_frame(0, (3700, 3701, 3702, 3703)), clock.now)
    device.handle_frame(0x220, bytes(8), clock.now)
    assert device.diagnostic_report().level == Level.OK  # the others: waiting since start
    assert not [v for k, v in device.diagnostic_report().values.items()
                if k.startswith('unknown')]
    clock.now += 2.0  # 2.5 s timeout (the profile): mux 1..3 not yet late
    device.handle_frame(0x220, bytes(8), clock.now)
    assert 'cell voltages unknown' not in device.diagnostic_report().message
    clock.now += 1.0  # 3 s since start: mux 1..3 late; mux 0 came 3 s ago: expired
    device.handle_frame(0x220, bytes(8), clock.now)
    device.handle_frame(0x250, cells_frame(0, (3700, 3701, 3702, 3703)), clock.now)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert '12 of 16 cell voltages unknown: f_CellVoltages mux 1..3 not received' \
        in diag.message
    assert diag.values['unknown 1'].startswith('12 of 16 cell voltages unknown')
    report = device.battery_report()
    assert report.cell_voltage[:4] == pytest.approx([3.7, 3.701, 3.702, 3.703])
    assert all(math.isnan(v) for v in report.cell_voltage[4:])  # BatteryState stays honest
    # mux 0 expired too: it came 3 s apart, so its timeout is 3 x 3 s (issue 35.5)
    clock.now += 9.5
    device.handle_frame(0x220, bytes(8), clock.now)
    assert '16 of 16 cell voltages unknown: f_CellVoltages mux 1..3 not received, mux 0 ' \
        'expired;' in device.diagnostic_report().message


def test_a_scalar_whose_message_is_missing_warns_and_a_flagged_cell_is_named(tmp_path):
    clock = Clock(0.0)
    device = DbcDevice('pack', write_files(tmp_path), clock)
    for name in ('state', 'minmax', 'cells0', 'cells1', 'temps0', 'temps1', 'pack'):
        device.handle_frame(*FRAMES[name], clock.now)  # no SoC frame
    assert 'percentage' not in device.diagnostic_report().message  # within its timeout
    clock.now = 0.9
    for name in ('state', 'minmax', 'cells0', 'cells1', 'temps0', 'temps1', 'pack'):
        device.handle_frame(*FRAMES[name], clock.now)
    clock.now = 1.2  # 1 s timeout since start passed
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'percentage unknown: BMS_StateEstimation not received' in diag.message
    # cell 003's flag is set in cells1: the BMS says it has no valid value
    assert '1 of 4 cell voltages unknown: 1 flagged invalid by the BMS' in diag.message
    assert math.isnan(device.battery_report().percentage)


# --- 8. diagnostics a monitor can carry ------------------------------------------------------
def test_values_all_on_foxbms_is_capped_ordered_naturally_without_the_multiplexer(tmp_path):
    mapping = profile_files('foxbms2')[1].read_text().replace(
        '  values: [f_BmsState, f_PackValuesP0, f_PackStateEstimation, f_PackMinMaxCellVoltage,'
        '\n           f_PackMinMaxCellTemperature, f_PackLimits, f_StringValuesP0,\n'
        '           f_StringMinMaxCellTemperature]', '  values: all')
    assert 'values: all' in mapping
    clock = Clock(0.0)
    device = foxbms(clock, mapping, tmp_path)
    total = sum(len(m.signals) for m in device.plan.messages)
    assert total > 800  # 54 x 4 cells with flags, 30 x 6 temperatures, ...
    device.handle_frame(0x220, bytes(8), 0.0)
    values = device.diagnostic_report().values
    signals = [k for k in values if '.' in k]
    mapped = [k for k in signals if k.startswith(('f_CellVoltages.CellVoltage_0',
                                                  'f_CellVoltages.CellVoltage_1'))]
    assert len(signals) <= VALUES_CAP + len(device.plan.mapped)
    left = len(device.plan.values) - len(signals)
    assert left > 500 and values['values not shown'].startswith(f'{left} more signals')
    # every mapped cell stays, in natural order, the multiplexer itself left out
    for cell in range(18):
        assert f'f_CellVoltages.CellVoltage_{cell:03d} [mV]' in values
    order = [k for k in signals if k.startswith('f_CellVoltages.CellVoltage_')]
    assert order[:4] == ['f_CellVoltages.CellVoltage_000 [mV]',
                         'f_CellVoltages.CellVoltage_000_invalidFlag',
                         'f_CellVoltages.CellVoltage_001 [mV]',
                         'f_CellVoltages.CellVoltage_001_invalidFlag']
    assert mapped and not any('_Mux' in k for k in signals)
    assert len(repr(values)) < 20000  # a status, not 50 KB


# --- 9. a simulator that behaves like a BMS ----------------------------------------------------
def _run(sim: DbcSimulator, device: DbcDevice, clock: Clock, seconds: float,
         seen: list | None = None) -> None:
    for step in range(int(seconds / 0.01)):
        clock.now = step * 0.01
        for frame in sim.tick(clock.now):
            if seen is not None:
                seen.append(frame)
            device.handle_frame(frame.arbitration_id, frame.data, clock.now)


def _simulate(profile: str, seconds: float) -> tuple[DbcDevice, list, Any]:
    """Run a profile's simulator into its device; return it, the frames and the DBC."""
    sim = DbcSimulator('pack', profile=profile)
    clock = Clock(0.0)
    device = DbcDevice('pack', {'profile': profile}, clock)
    frames: list = []
    _run(sim, device, clock, seconds, frames)
    return device, frames, cantools.database.load_file(str(profile_files(profile)[0]))


def test_the_simulator_sends_the_dbcs_units_and_meaning():
    device, frames, db = _simulate('orion_bms2', 1.0)
    soc = [db.decode_message(f.arbitration_id, f.data)['Pack_SOC'] for f in frames
           if f.arbitration_id == 0x6B0]
    assert len(soc) > 90 and all(30 <= s <= 90 for s in soc)  # Percent, as the BMS sends
    assert 0.3 <= device.battery_report().percentage <= 0.9
    assert device.diagnostic_report().level == Level.OK


def test_the_simulator_sends_valid_flags_by_their_table_and_one_mux_a_period():
    device, frames, db = _simulate('foxbms2', 3.0)
    cells = [db.decode_message(0x250, f.data, decode_choices=False) for f in frames
             if f.arbitration_id == 0x250]
    assert {c['f_CellVoltages_Mux'] for c in cells} == {0, 1, 2, 3, 4}  # 18 cells: 5 values
    assert cells[0]['CellVoltage_000_invalidFlag'] == 1  # 1 "Valid", as the firmware sends
    assert 25 <= len(cells) <= 32  # one frame every 100 ms (5400 ms / 54 values)
    report = device.battery_report()
    assert all(3.0 < v < 4.3 for v in report.cell_voltage)
    assert device.diagnostic_report().level == Level.OK, device.diagnostic_report().message


def test_a_mapping_that_reads_the_dbc_wrong_shows_wrong_values_in_simulation(tmp_path):
    # the mapping claims the DBC's mV are V: the simulator sends mV all the same
    mapping = OUR_MAPPING.replace('voltage: BMS_PackValues.batteryVoltage',
                                  'voltage: {signal: BMS_PackValues.batteryVoltage, unit: V}')
    files = write_files(tmp_path, mapping=mapping)
    sim = DbcSimulator('pack', files['dbc_file'], files['mapping_file'])
    clock = Clock(0.0)
    device = DbcDevice('pack', files, clock)
    _run(sim, device, clock, 1.0)
    # mV read as V: 400000 V, no pack's (issue 35.6): never published, counted, named
    assert math.isnan(device.battery_report().voltage)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and device.frames_malformed > 0
    assert 'implausible: BMS_PackValues.batteryVoltage = ' in diag.message
    assert 'implausible for voltage 0..1500 V' in device.last_malformed
