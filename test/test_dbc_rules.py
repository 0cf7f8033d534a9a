# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The dbc mapping's rules on real-style files.

Loading, validity flags, units, the scale rule, the start log, timeouts from the DBC, bit
masks in levels, paths and YAML errors.

The DBCs are our hand-written BMS (test/fixtures/our_bms.dbc) changed the way real files
are: units as the Orion utility and Volkswagen spell them, flags with a Valid/Invalid table
as foxBMS 2 writes them, lines cantools refuses even without strict (as in commaai/opendbc).
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.protocols.dbc_mapping.plan import set_params_files
from ams_can_bridge.protocols.dbc_load import read_dbc
from dbc_fixtures import FRAMES, OUR_BMS_DBC, OUR_MAPPING, write_files
from helpers import Clock

ALL = ('state', 'soc', 'minmax', 'cells0', 'cells1', 'temps0', 'temps1', 'pack')


def make(tmp_path: Path, mapping: str = OUR_MAPPING, dbc: str = OUR_BMS_DBC,
         clock: Clock | None = None, **params) -> DbcDevice:
    return DbcDevice('pack', {**write_files(tmp_path, dbc, mapping), **params},
                     clock or Clock())


def problems_of(tmp_path: Path, mapping: str = OUR_MAPPING, dbc: str = OUR_BMS_DBC) -> str:
    with pytest.raises(ValueError) as info:
        make(tmp_path, mapping, dbc)
    return str(info.value)


def feed(device: DbcDevice, *names: str, stamp: float = 1.0) -> None:
    for name in names:
        device.handle_frame(*FRAMES[name], stamp)


# --- 1. load what can be loaded ------------------------------------------------------------
def test_lines_cantools_refuses_even_without_strict_are_dropped_and_said(tmp_path):
    dbc = OUR_BMS_DBC.replace(
        'VAL_ 544 mode',
        # opendbc's tesla_can.dbc: a value table of a signal the DBC does not have
        'VAL_ 568 UI_mapSpeedLimit 31 "SNA" 30 "UNLIMITED" ;\n'
        # opendbc's mazda_2017.dbc: a message name cantools cannot parse, with its signal
        'BO_ 1275 2017_5: 8 XXX\n SG_ counter : 4|5@0+ (1,0) [0|255] "" XXX\n\n'
        # opendbc's chrysler_cusw.dbc: a standard ID over 11 bits
        'BO_ 103596083 BSM_LEFT: 8 XXX\n SG_ LEFT_DETECTED : 21|1@0+ (1,0) [0|1] "" XXX\n\n'
        'VAL_ 544 mode')
    loaded = read_dbc(write_files(tmp_path, dbc)['dbc_file'])
    notes = loaded.notes()
    assert len(notes) == 3 and not loaded.strict, notes
    assert any('(value table of no signal): VAL_ 568 UI_mapSpeedLimit' in n for n in notes)
    assert any('(cantools cannot parse it): BO_ 1275 2017_5: 8 XXX with its 1 SG_ line(s)'
               in n for n in notes)
    assert any('(message BSM_LEFT: a standard ID over 11 bits)' in n for n in notes)
    device = make(tmp_path, dbc=dbc)  # the mapped messages work
    feed(device, *ALL)
    assert device.battery_report().voltage == pytest.approx(400.0)
    # parts the mapping does not use: said at start, never a lasting level (issue 35.4)
    assert len(device.start_log()[1]) == 3
    diag = device.diagnostic_report()
    assert 'DBC' not in diag.message  # its WARN is the fixture's invalid cell's alone
    assert diag.message == '1 of 4 cell voltages unknown: 1 flagged invalid by the BMS'
    assert 'UI_mapSpeedLimit' in diag.values['DBC note 3']


def test_a_file_that_is_no_dbc_is_one_clear_problem(tmp_path):
    text = problems_of(tmp_path, dbc='this is not a DBC\n')
    assert text.startswith(f"dbc_file '{tmp_path / 'our_bms.dbc'}' does not load: ")
    assert 'Traceback' not in text


def test_a_broken_unmapped_message_warns_and_the_rest_works(tmp_path):
    # a signal that does not fit its message, in a message the mapping does not read
    dbc = OUR_BMS_DBC.replace('VAL_ 544 mode', 'BO_ 700 Unrelated: 2 BMS\n'
                              ' SG_ too_long : 8|16@1+ (1,0) [0|0] "" Vector__XXX\n\n'
                              'VAL_ 544 mode')
    device = make(tmp_path, dbc=dbc)
    assert device.start_log()[1] == ['DBC message Unrelated is broken and unusable: The '
                                     'signal too_long does not fit']
    feed(device, *ALL)
    assert device.battery_report().percentage == pytest.approx(0.875)


# --- 2. validity flags as the DBC means them -------------------------------------------------
FLAG_TABLE = ('VAL_ 576 cellVoltage_{0:03d}_invalidFlag 0 "{1}" 1 "{2}" ;\n')


def _with_table(names: tuple[str, str]) -> str:
    return OUR_BMS_DBC + ''.join(FLAG_TABLE.format(i, *names) for i in range(4))


@pytest.mark.parametrize('names', [('Invalid', 'Valid'), ('INVALID', 'valid'),
                                   ('invalid', 'VALID')])
def test_a_flag_whose_table_names_0_invalid_is_read_by_those_names(tmp_path, names):
    device = make(tmp_path, dbc=_with_table(names))
    assert 'invalid when BMS_CellVoltages.cellVoltage_{i:03d}_invalidFlag = 0 (the DBC ' \
        f'value table names 0 "{names[0]}")' in '\n'.join(device.start_log()[0])
    feed(device, 'pack', 'cells0', 'cells1')  # flags 0, 0 | 0, 1
    cells = device.battery_report().cell_voltage
    assert [math.isnan(v) for v in cells] == [True, True, True, False]
    assert cells[3] == pytest.approx(3.72)


def test_valid_key_and_when_say_it_explicitly_without_a_table(tmp_path):
    mapping = OUR_MAPPING.replace('invalid: "BMS_CellVoltages.cellVoltage_{i:03d}_invalidFlag"',
                                  'valid: "BMS_CellVoltages.cellVoltage_{i:03d}_invalidFlag"')
    device = make(tmp_path, mapping)  # valid:, no table: 0 means invalid
    feed(device, 'pack', 'cells1')
    assert [math.isnan(v) for v in device.battery_report().cell_voltage[2:]] == [True, False]
    mapping = OUR_MAPPING.replace(
        'invalid: "BMS_CellVoltages.cellVoltage_{i:03d}_invalidFlag"',
        'invalid: {signal: "BMS_CellVoltages.cellVoltage_{i:03d}_invalidFlag", when: 0}')
    device = make(tmp_path, mapping)
    assert '= 0 (the mapping: invalid: {when: 0})' in '\n'.join(device.start_log()[0])
    feed(device, 'pack', 'cells1')
    assert [math.isnan(v) for v in device.battery_report().cell_voltage[2:]] == [True, False]


def test_when_that_contradicts_the_value_table_stops(tmp_path):
    mapping = OUR_MAPPING.replace(
        'invalid: "BMS_CellVoltages.cellVoltage_{i:03d}_invalidFlag"',
        'invalid: {signal: "BMS_CellVoltages.cellVoltage_{i:03d}_invalidFlag", when: 1}')
    text = problems_of(tmp_path, mapping, _with_table(('Invalid', 'Valid')))
    assert "when 1 calls 1 invalid, but the DBC's value table of cellVoltage_000_invalidFlag " \
        'says it is not (the DBC value table names 0 "Invalid")' in text


# --- 3. units as real DBCs spell them ------------------------------------------------------
@pytest.mark.parametrize('spelled', [
    ('Volts', 'Amps', 'Percent', 'Celsius'),  # the Orion BMS utility's export
    ('Unit_Volt', 'Unit_Amper', 'Unit_PerCent', 'Unit_DegreCelsi'),  # Volkswagen
    ('VOLT', 'amperes', 'percentage', 'deg C'),
])
def test_units_are_read_case_insensitively_with_long_and_plural_forms(tmp_path, spelled):
    volt, amp, percent, celsius = spelled
    dbc = (OUR_BMS_DBC
           .replace('(10,0) [0|600000] "mV"', f'(0.01,0) [0|600] "{volt}"')
           .replace('(1,0) [-1000000|1000000] "mA"', f'(0.001,0) [-1000|1000] "{amp}"')
           .replace('[0|100] "%"', f'[0|100] "{percent}"')
           .replace('[-40|125] "degC" Vector__XXX\n SG_ minimumCellVoltage',
                    f'[-40|125] "{celsius}" Vector__XXX\n SG_ minimumCellVoltage'))
    device = make(tmp_path, dbc=dbc)
    assert device.warnings == []
    feed(device, *ALL)
    report = device.battery_report()
    assert report.voltage == pytest.approx(400.0) and report.current == pytest.approx(-50.0)
    assert report.percentage == pytest.approx(0.875)  # Percent -> 0..1 like %
    assert report.temperature == 35.0


def test_amphours_and_kelvin_convert(tmp_path):
    dbc = OUR_BMS_DBC.replace('[0|100] "%"', '[0|100] "Amp-hours"').replace(
        '(1,0) [-40|125] "degC" Vector__XXX\n SG_ minimumCellVoltage',
        '(1,200) [-40|455] "Kelvin" Vector__XXX\n SG_ minimumCellVoltage')
    mapping = OUR_MAPPING.replace('percentage: BMS_StateEstimation.packSoc',
                                  'charge: BMS_StateEstimation.packSoc')
    device = make(tmp_path, mapping, dbc)
    feed(device, *ALL)
    report = device.battery_report()
    assert report.charge == pytest.approx(87.5)
    assert report.temperature == pytest.approx(35 + 200 - 273.15)


def test_a_unit_of_another_quantity_stops(tmp_path):
    dbc = OUR_BMS_DBC.replace('(10,0) [0|600000] "mV"', '(10,0) [0|600000] "kWh"')
    text = problems_of(tmp_path, dbc=dbc)
    assert 'battery_state.voltage: BMS_PackValues.batteryVoltage is in kWh, an energy, not ' \
        'a voltage' in text


# --- 4. say the formula; the scale rule ----------------------------------------------------
def test_a_scale_on_a_converted_unit_is_the_common_mistake_and_stops(tmp_path):
    mapping = OUR_MAPPING.replace('percentage: BMS_StateEstimation.packSoc',
                                  'percentage: {signal: BMS_StateEstimation.packSoc, '
                                  'scale: 0.01}')
    text = problems_of(tmp_path, mapping)
    assert ('battery_state.percentage: BMS_StateEstimation.packSoc is in %, which the device '
            'converts to 0..1 itself; scale 0.01 on top would make 75 % read 0.0075') in text
    assert 'Remove scale (scale: -1 only flips the sign)' in text


def test_unit_key_says_what_a_wrong_dbc_unit_should_be(tmp_path):
    dbc = OUR_BMS_DBC.replace('(10,0) [0|600000] "mV"', '(10,0) [0|600000] "V"')  # wrong
    mapping = OUR_MAPPING.replace('voltage: BMS_PackValues.batteryVoltage',
                                  'voltage: {signal: BMS_PackValues.batteryVoltage, unit: mV}')
    device = make(tmp_path, mapping, dbc)
    feed(device, *ALL)
    assert device.battery_report().voltage == pytest.approx(400.0)
    assert 'voltage [V] = BMS_PackValues.batteryVoltage [mV] x 0.001' in device.start_log()[0]


def test_the_start_log_says_each_formula_and_the_thresholds_unit(tmp_path):
    lines = make(tmp_path).start_log()[0]
    assert 'voltage [V] = BMS_PackValues.batteryVoltage [mV] x 0.001' in lines
    assert 'current [A] = BMS_PackValues.packCurrent [mA] x 0.001 x -1 (scale)' in lines
    assert 'percentage [0..1] = BMS_StateEstimation.packSoc [%] x 0.01' in lines
    assert 'design_capacity [Ah] = 20 (a constant)' in lines
    assert 'levels[1]: WARN when BMS_MinMax.minimumCellVoltage < 3000 mV (the DBC value, in ' \
        'its own unit)' in lines


# --- 5. timeouts from the DBC ----------------------------------------------------------------
CYCLES = ('BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;\n'
          'BA_DEF_DEF_ "GenMsgCycleTime" 0;\n'
          'BA_ "GenMsgCycleTime" BO_ 565 1000;\n'
          'BA_ "GenMsgCycleTime" BO_ 561 10;\n'
          'BA_ "GenMsgCycleTime" BO_ 576 200;\n')


def test_timeouts_come_from_the_dbc_period_and_the_mapping_overrides(tmp_path):
    mapping = OUR_MAPPING + 'timeouts:\n  BMS_CellTemperatures: 7.5\n'
    clock = Clock(0.0)
    device = make(tmp_path, mapping, OUR_BMS_DBC + CYCLES, clock)
    lines = device.start_log()[0]
    assert 'timeout BMS_StateEstimation (0x235): 5 s, 5 x GenMsgCycleTime 1000 ms' in lines
    assert 'timeout BMS_MinMax (0x231): 0.1 s, 5 x GenMsgCycleTime 10 ms' in lines  # floor
    # multiplexed: the whole rotation, 200 ms x 2 multiplexer values, five times
    assert 'timeout BMS_CellVoltages (0x240): 2 s, 5 x GenMsgCycleTime 200 ms x 2 ' \
        'multiplexer values' in lines
    assert "timeout BMS_CellTemperatures (0x250): 7.5 s, the mapping's timeouts" in lines
    assert 'timeout BMS_State (0x220): 1 s, stale_timeout (the DBC gives no period)' in lines
    feed(device, *ALL)
    clock.now = 1.9  # cells fresh (2 s); SoC fresh (5 s); pack 0.9 s: not stale
    device.handle_frame(*FRAMES['pack'], 1.9)
    report = device.battery_report()
    assert report.cell_voltage[0] == pytest.approx(3.70) and report.percentage > 0.8
    clock.now = 2.5
    device.handle_frame(*FRAMES['pack'], 2.5)
    report = device.battery_report()
    assert math.isnan(report.cell_voltage[0]) and report.percentage > 0.8
    assert report.cell_temperature[0] == 25.0  # 7.5 s


# --- 7. bit fields in level rules ------------------------------------------------------------
def test_any_bits_and_all_bits_levels(tmp_path):
    mapping = OUR_MAPPING.replace(
        '  levels:\n',
        '  levels:\n'
        '    - {signal: BMS_State.error, all_bits: 0x0C, level: ERROR, message: "both {bits}"}\n'
        '    - {signal: BMS_State.error, any_bits: 0x0C, level: WARN, message: "one {bits}"}\n')
    device = make(tmp_path, mapping)
    feed(device, *ALL)
    device.handle_frame(0x240, bytes.fromhex('016A0E880E000000'), 1.0)  # no flagged cell
    assert device.diagnostic_report().level == Level.OK
    device.handle_frame(0x220, bytes([2, 0x04]), 2.0)  # error 0x04: one of the bits
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and diag.message.startswith('one 0x4')
    device.handle_frame(0x220, bytes([2, 0x0D]), 2.0)  # 0x0D: both bits (and 0x01)
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR and diag.message.startswith('both 0xC')
    device.handle_frame(0x220, bytes([2, 0x01]), 2.0)  # none of 0x0C: the next rule
    assert device.diagnostic_report().message.startswith('BMS error 1')


def test_a_mask_beyond_the_signal_or_not_a_mask_stops(tmp_path):
    mapping = OUR_MAPPING.replace(
        '  levels:\n', '  levels:\n    - {signal: BMS_State.error, any_bits: 0x100, '
        'level: WARN}\n    - {signal: BMS_State.error, all_bits: -1, level: WARN}\n')
    text = problems_of(tmp_path, mapping)
    assert '0x100 has bits beyond the 8 bits of error' in text
    assert '-1 is not a bit mask' in text


# --- 10. paths ---------------------------------------------------------------------------
def test_relative_paths_are_found_beside_the_params_file(tmp_path, monkeypatch):
    folder = tmp_path / 'car'
    folder.mkdir()
    write_files(folder)
    params = folder / 'params.yaml'
    params.write_text('')
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    config = {'dbc_file': 'our_bms.dbc', 'mapping_file': 'pack_mapping.yaml'}
    try:
        with pytest.raises(ValueError) as info:
            DbcDevice('pack', config, Clock())
        set_params_files([str(params)])
        device = DbcDevice('pack', config, Clock())
    finally:
        set_params_files([])
    text = str(info.value)
    assert f"dbc_file 'our_bms.dbc' not found; looked in: {elsewhere / 'our_bms.dbc'}" in text
    assert 'share' not in text or 'our_bms.dbc' in text  # every place it looked
    assert device.plan.files == (str(folder / 'our_bms.dbc'),
                                 str(folder / 'pack_mapping.yaml'))


# --- the YAML papercut (issue 31) ------------------------------------------------------------
def test_a_yaml_error_keeps_its_own_lines_with_file_line_and_column(tmp_path):
    bad = OUR_MAPPING.replace('  voltage: BMS_PackValues.batteryVoltage',
                              '  voltage: BMS_PackValues.batteryVoltage: oops')
    text = problems_of(tmp_path, bad)
    line = OUR_MAPPING.splitlines().index('  voltage: BMS_PackValues.batteryVoltage') + 1
    assert text.startswith(f"mapping_file {tmp_path / 'pack_mapping.yaml'}, line {line}, "
                           'column 41: not valid YAML: mapping values are not allowed here')
    lines = text.splitlines()
    assert len(lines) == 3 and ';' not in lines[0]  # YAML's own snippet, not flattened
    assert lines[1].strip().endswith('BMS_PackValues.batteryVoltage: oops')
    assert lines[2].strip() == '^' and lines[1][lines[2].index('^')] == ':'
