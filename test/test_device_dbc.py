# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The dbc device: a team's DBC + mapping -> BatteryState, diagnostics; every validation error.

Frames are hand-written from the DBC in dbc_fixtures.py; the AMS equality test feeds the
same frames to the built-in ams device and to config/ams_dbc_mapping.yaml over
msg_defs/ams.dbc.
"""
from __future__ import annotations

import math
from pathlib import Path

import cantools
import pytest

from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.devices.base import Level, PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols import ams as proto
from ams_can_bridge.protocols import dbc_codec
from ams_can_bridge.protocols.ams import AmsCodec
from dbc_fixtures import FRAMES, OUR_BMS_DBC, OUR_MAPPING, write_files
from helpers import Clock, same
from shared import published as _published

REPO = Path(__file__).resolve().parents[1]


def make(tmp_path: Path, mapping: str = OUR_MAPPING, dbc: str = OUR_BMS_DBC,
         clock: Clock | None = None) -> DbcDevice:
    return DbcDevice('pack', write_files(tmp_path, dbc, mapping), clock or Clock())


def feed(device: DbcDevice, *names: str) -> list[bool]:
    return [device.handle_frame(*FRAMES[name], 1.0) for name in names]


def problems_of(tmp_path: Path, mapping: str, dbc: str = OUR_BMS_DBC) -> str:
    with pytest.raises(ValueError) as info:
        make(tmp_path, mapping, dbc)
    return str(info.value)


ALL = ('state', 'soc', 'minmax', 'cells0', 'cells1', 'temps0', 'temps1', 'pack')


# --- the contract example, end to end without ROS --------------------------------------------
def test_contract_example_gives_batterystate_in_ros_units(tmp_path):
    device = make(tmp_path)
    primaries = feed(device, *ALL)
    assert primaries == [False] * 7 + [True]  # one BatteryState per BMS_PackValues frame
    report = device.battery_report()
    assert report.present is True
    assert report.voltage == pytest.approx(400.0)  # 40000 x 10 mV
    assert report.current == pytest.approx(-50.0)  # 50000 mA discharging, scale -1
    assert report.percentage == pytest.approx(0.875)  # 87.5 % -> 0..1
    assert report.temperature == 35.0
    assert report.cell_voltage[:3] == pytest.approx([3.70, 3.71, 3.69])
    assert math.isnan(report.cell_voltage[3])  # its invalid flag is set
    assert report.cell_temperature == [25.0, 26.0, 27.0, -30.0]
    assert report.power_supply_status == PowerSupplyStatus.DISCHARGING  # mode DRIVE
    assert report.power_supply_health == PowerSupplyHealth.GOOD  # error 0
    assert report.design_capacity == 20.0
    assert report.stamp == 1.0


def test_frame_ids_are_exactly_the_referenced_messages(tmp_path):
    device = make(tmp_path)
    assert device.frame_ids == {(0x220, False), (0x222, False), (0x231, False), (0x235, False),
                                (0x240, False), (0x250, False)}


def test_health_otherwise_and_status_from_map(tmp_path):
    device = make(tmp_path)
    feed(device, 'pack')
    device.handle_frame(0x220, bytes([1, 7]), 2.0)  # CHARGE, error 7
    report = device.battery_report()
    assert report.power_supply_status == PowerSupplyStatus.CHARGING
    assert report.power_supply_health == PowerSupplyHealth.UNSPEC_FAILURE
    device.handle_frame(0x220, bytes([0, 0]), 2.0)  # STANDBY: not in the map
    # no map entry: from the current, as the built-in devices (-50 A: discharging)
    assert device.battery_report().power_supply_status == PowerSupplyStatus.DISCHARGING


# --- out of range and invalid flags --------------------------------------------------------
def test_value_outside_dbc_range_is_nan_and_malformed(tmp_path):
    device = make(tmp_path)
    feed(device, *ALL)
    # mux 0: cell 000 = 0x1770 = 6000 mV > [0|5000]; cell 001 = 3710 mV
    device.handle_frame(0x240, bytes.fromhex('0070177E0E000000'), 2.0)
    report = device.battery_report()
    assert math.isnan(report.cell_voltage[0])
    assert report.cell_voltage[1] == pytest.approx(3.71)  # the rest of the frame is used
    assert device.frames_malformed == 2  # this one and the invalid flag of cells1
    assert 'cellVoltage_000 outside its DBC range' in device.last_malformed
    values = device.diagnostic_report().values
    assert values['BMS_CellVoltages.cellVoltage_000 [mV]'] == 'unknown'  # never shown as data
    # SoC raw 1001 = 100.1 % > [0|100]
    device.handle_frame(0x235, bytes.fromhex('E903'), 2.0)
    assert math.isnan(device.battery_report().percentage)


def test_invalid_flag_makes_the_cell_nan_and_counts_malformed(tmp_path):
    device = make(tmp_path)
    feed(device, 'pack', 'cells1')
    report = device.battery_report()
    assert report.cell_voltage[2] == pytest.approx(3.69)
    assert math.isnan(report.cell_voltage[3])
    assert device.frames_malformed == 1
    assert 'cell_voltage[3] (BMS_CellVoltages.cellVoltage_003_invalidFlag) flagged invalid' \
        in device.last_malformed
    device.handle_frame(0x240, bytes.fromhex('016A0E880E000000'), 2.0)  # flag cleared
    assert device.battery_report().cell_voltage[3] == pytest.approx(3.72)
    assert device.frames_malformed == 1


def test_short_frame_and_unknown_mux_are_malformed_and_change_nothing(tmp_path):
    device = make(tmp_path)
    feed(device, *ALL)
    before = device.battery_report()
    assert device.handle_frame(0x222, bytes(3), 2.0) is False  # DLC 3, expected 8
    device.handle_frame(0x240, bytes.fromhex('0500000000000000'), 2.0)  # mux 5: no branch
    assert device.frames_malformed == 3
    assert 'multiplexer value 5' in device.last_malformed
    assert same(tuple(before.cell_voltage), tuple(device.battery_report().cell_voltage))


# --- staleness: each group on its own --------------------------------------------------------
def test_each_group_expires_on_its_own_and_the_primary_makes_stale(tmp_path):
    clock = Clock()
    device = make(tmp_path, clock=clock)
    feed(device, *ALL)
    clock.now += 0.8
    feed(device, 'pack', 'cells0')  # the pack and the first cell frame keep coming
    clock.now += 0.5  # 1.3 s after the others: expired; pack and cells0 0.5 s old
    report = device.battery_report()
    assert report.present is True and report.voltage == pytest.approx(400.0)
    assert math.isnan(report.percentage) and math.isnan(report.temperature)
    assert report.cell_voltage[0] == pytest.approx(3.70)
    assert math.isnan(report.cell_voltage[2])  # mux 1 is a group of its own
    assert report.power_supply_health == PowerSupplyHealth.UNKNOWN
    diag = device.diagnostic_report()
    assert 'BMS_MinMax' in diag.values['messages expired']
    assert 'BMS_PackValues' not in diag.values['messages expired']
    clock.now += 1.0  # the primary silent for 1.5 s > stale_timeout 1.0
    report = device.battery_report()
    assert report.present is False and math.isnan(report.voltage)
    assert device.diagnostic_report().level == Level.STALE


# --- diagnostics ---------------------------------------------------------------------------
def test_diagnostics_values_with_units_and_first_matching_level(tmp_path):
    device = make(tmp_path)
    feed(device, *ALL)
    device.handle_frame(0x240, bytes.fromhex('016A0E880E000000'), 2.0)  # cell 003 valid again
    diag = device.diagnostic_report()
    assert diag.level == Level.OK
    assert diag.values['BMS_PackValues.batteryVoltage [mV]'] == '400000'
    assert diag.values['BMS_State.mode'] == 'DRIVE (2)'
    assert diag.values['BMS_MinMax.maximumCellTemp [degC]'] == '35'
    device.handle_frame(0x231, bytes.fromhex('23B80B00'), 2.0)  # min cell 3000 mV: not below
    assert device.diagnostic_report().level == Level.OK
    device.handle_frame(0x231, bytes.fromhex('23B70B00'), 2.0)  # 2999 mV
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'BMS_MinMax.minimumCellVoltage 2999' in diag.message
    device.handle_frame(0x220, bytes([2, 9]), 2.0)  # error 9: the first rule wins
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR and diag.message.startswith('BMS error 9')
    assert device.diagnostic_level() == Level.ERROR


# --- validation: every problem at once, named, with the closest names --------------------------
def test_typod_signal_names_the_closest(tmp_path):
    text = problems_of(tmp_path, OUR_MAPPING.replace('batteryVoltage', 'batteryVoltag'))
    assert "signal 'batteryVoltag' is not in message BMS_PackValues; closest: batteryVoltage" \
        in text


def test_typod_message_names_the_closest(tmp_path):
    text = problems_of(tmp_path, OUR_MAPPING.replace('BMS_MinMax.', 'BMS_MinMx.'))
    assert "message 'BMS_MinMx' is not in the DBC; closest: BMS_MinMax" in text


def test_missing_primary(tmp_path):
    text = problems_of(tmp_path, OUR_MAPPING.replace('primary: BMS_PackValues\n', ''))
    assert 'primary is not set' in text


def test_every_problem_is_listed_together(tmp_path):
    mapping = (OUR_MAPPING.replace('primary: BMS_PackValues\n', '')
               .replace('packSoc', 'packSOC').replace('count: 4\n', 'count: 5\n', 1)
               .replace('{0: GOOD}', '{0: GODO}').replace('below: 3000', 'bellow: 3000'))
    text = problems_of(tmp_path, mapping)
    for words in ('primary is not set', "'packSOC'", 'cellVoltage_004',
                  "'GODO' is not a PowerSupplyHealth name; closest: GOOD",
                  "unknown key 'bellow'; closest: below"):
        assert words in text, (words, text)


def test_array_template_that_does_not_resolve(tmp_path):
    text = problems_of(tmp_path, OUR_MAPPING.replace('cellVoltage_{i:03d}"', 'cellVoltage_{j}"'))
    assert 'does not resolve with {i}' in text
    text = problems_of(tmp_path, OUR_MAPPING.replace('count: 4\n', 'count: 6\n', 1))
    assert "'cellVoltage_004' is not in message BMS_CellVoltages" in text


def test_map_key_must_be_a_value_name(tmp_path):
    text = problems_of(tmp_path, OUR_MAPPING.replace('{CHARGE: CHARGING', '{CHARGING: CHARGING'))
    assert "'CHARGING' is not a value name of mode; closest: CHARGE" in text


def test_a_mapped_signal_of_a_broken_message_stops_naming_the_message_and_why(tmp_path):
    overlapping = OUR_BMS_DBC.replace('error : 8|8@1+', 'error : 2|8@1+')
    text = problems_of(tmp_path, OUR_MAPPING, overlapping)
    assert 'message BMS_State is broken in the DBC (The signals error and mode are ' \
        'overlapping)' in text


def test_missing_files(tmp_path):
    with pytest.raises(ValueError) as info:
        DbcDevice('pack', {'dbc_file': str(tmp_path / 'none.dbc')}, Clock())
    assert 'none.dbc' in str(info.value) and 'not found' in str(info.value)
    assert 'mapping_file is not set' in str(info.value)


def test_unknown_unit_without_scale_is_a_warning_naming_the_signal(tmp_path):
    mapping = OUR_MAPPING.replace('voltage: BMS_PackValues.batteryVoltage',
                                  'voltage: BMS_State.error')
    device = make(tmp_path, mapping)
    assert any('BMS_State.error has unit' in w for w in device.start_log()[1])
    feed(device, *ALL)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'mapping warning' in diag.message
    assert 'BMS_State.error' in diag.values['mapping warning 1']
    # with a scale the user said how: no warning
    device = make(tmp_path, mapping.replace('voltage: BMS_State.error',
                                            'voltage: {signal: BMS_State.error, scale: 1}'))
    assert device.warnings == []


def test_known_units_convert_without_a_scale(tmp_path):
    dbc = (OUR_BMS_DBC
           .replace('batteryVoltage : 7|16@0+ (10,0) [0|600000] "mV"',
                    'batteryVoltage : 7|16@0+ (1e-05,0) [0|0.6] "kV"')  # 40000 -> 0.4 kV
           .replace('maximumCellTemp : 0|8@1- (1,0) [-40|125] "degC"',
                    'maximumCellTemp : 0|8@1+ (10,0) [0|2550] "K"')  # 0x23 -> 350 K
           .replace('packSoc : 0|10@1+ (0.1,0) [0|100] "%"',
                    'packSoc : 0|10@1+ (1,0) [0|1000] "\u2030"'))  # 875 per mille
    device = make(tmp_path, dbc=dbc)
    assert device.warnings == []
    feed(device, *ALL)
    report = device.battery_report()
    assert report.voltage == pytest.approx(400.0)
    assert report.temperature == pytest.approx(350 - 273.15)
    assert report.percentage == pytest.approx(0.875)
    assert report.current == pytest.approx(-50.0)  # mA and the mapping's scale -1


def test_dbc_instance_in_a_device_set_refuses_with_config_error(tmp_path):
    params = write_files(tmp_path, OUR_BMS_DBC, OUR_MAPPING.replace('packSoc', 'packSco'))
    values = {'pack.type': 'dbc', **{f'pack.{k}': v for k, v in params.items()}}
    with pytest.raises(ConfigError) as info:
        DeviceSet(['pack'], lambda name, spec: values.get(name, spec.default))
    assert "device 'pack' (dbc)" in str(info.value) and 'packSco' in str(info.value)


# --- compiled decoding = cantools ----------------------------------------------------------
def test_compiled_decoding_matches_cantools_on_every_message(tmp_path):
    import random
    rng = random.Random(7)
    db = cantools.database.load_string(OUR_BMS_DBC, strict=True)
    ams_db = cantools.database.load_file(str(REPO / 'msg_defs' / 'ams.dbc'), strict=True)
    for message in list(db.messages) + list(ams_db.messages):
        compiled = dbc_codec.compile_message(message)
        assert compiled.compiled, message.name
        for _ in range(300):
            data = bytes(rng.randrange(256) for _ in range(message.length))
            if compiled.mux_index is not None:
                data = bytes([rng.randrange(2)]) + data[1:]
            expected = message.decode(data, decode_choices=False)
            values, bad = compiled.decode(data)
            for i, signal in enumerate(compiled.signals):
                if signal.name not in expected:
                    assert values[i] is None
                elif i in bad:
                    value = expected[signal.name]
                    assert not signal.minimum <= value <= signal.maximum
                else:
                    assert values[i] == pytest.approx(expected[signal.name]), signal.name


# --- our AMS as a dbc device = the built-in ams device -----------------------------------------
def _ams_frames() -> list[tuple[int, bytes]]:
    codec = AmsCodec()
    frames = [
        # hand-written: IDLE with 5 banks (byte 1: bits 7..5 = 0b101, bits 4..0 = 1),
        # Volt_min 0xAF x 20 mV = 3.5 V, Temp_max 31, SOC 80 %, counter 1
        (0x300, bytes.fromhex('00A1AF1F500100')),
        # cell temperatures before any cell voltage: temperature from them, not Temp_max
        (0x312, bytes.fromhex('2019181A1C1B')),  # bank 1 group 0: 25, 24, 26, 28, 27
    ]
    for bank in range(1, 6):
        for group in range(4):
            volts = tuple(round(3.5 + 0.02 * ((bank * 7 + group * 3 + k) % 20), 2)
                          for k in range(7))
            frames.append(codec.encode(proto.CellVoltages(bank, group, volts))[:2])
        for group in range(2):
            frames.append(codec.encode(proto.CellTemperatures(
                bank, group, tuple(20 + bank + group + k for k in range(5))))[:2])
    word = proto.AmsStatusWord(bank_count=5, state=proto.AmsState.CHARGING)
    frames.append(codec.encode(proto.AmsStatus(word, 3.5, 40, 95, 2))[:2])
    for state, extra in ((proto.AmsState.DRIVE, {}), (proto.AmsState.ERROR, {}),
                         (proto.AmsState.IDLE, {'imd_error': True}),
                         (proto.AmsState.IDLE, {'ams_error': True})):
        word = proto.AmsStatusWord(bank_count=5, state=state, **extra)
        frames.append(codec.encode(proto.AmsStatus(word, 3.5, 41, 60, 3))[:2])
    frames.append((0x300, bytes.fromhex('00A1AF1F650400')))  # SOC 101 %: unknown for both
    frames.append((0x311, bytes.fromhex('2100000000000000')))  # bank 1 group 1: 0 V cells
    frames.append((0x300, bytes.fromhex('0081AF1F500500')))  # IDLE, 4 banks
    return frames


def test_ams_as_dbc_publishes_what_the_ams_device_publishes():
    clock = Clock()
    ams = AmsDevice('ams', {'bank_count': 5, 'stale_timeout': 0.5}, clock)
    dbc = DbcDevice('pack', {'dbc_file': str(REPO / 'msg_defs' / 'ams.dbc'),
                             'mapping_file': str(REPO / 'config' / 'ams_dbc_mapping.yaml'),
                             'stale_timeout': 0.5}, clock)
    assert dbc.warnings == []
    compared = 0
    for n, (can_id, data) in enumerate(_ams_frames()):
        clock.now += 0.001
        primary = ams.handle_frame(can_id, data, float(n))
        assert dbc.handle_frame(can_id, data, float(n)) is primary
        a, d = ams.battery_report(), dbc.battery_report()
        assert same(_published(a), _published(d)), (n, _published(a), _published(d))
        compared += primary
    assert compared == 8
    report = dbc.battery_report()  # the comparison saw real values, not only NaN
    assert report.present and report.power_supply_health == PowerSupplyHealth.GOOD
    assert len(report.cell_voltage) == 140 and report.cell_voltage[7] == 0.0
    assert math.isfinite(report.voltage) and report.temperature == 30.0


# --- the other forms of the mapping ------------------------------------------------------------
EXTENDED_DBC = '''VERSION ""

BS_:

BU_: BMS

BO_ 2566869221 ORION_Pack: 4 BMS
 SG_ pack_dcl : 0|16@1+ (1,0) [0|0] "A" Vector__XXX
 SG_ pack_voltage : 16|16@1+ (0.1,0) [0|6553.5] "V" Vector__XXX

BO_ 1712 ORION_Cells: 4 BMS
 SG_ cell_a : 0|16@1+ (0.0001,0) [0|6.5535] "V" Vector__XXX
 SG_ cell_b : 16|16@1+ (0.0001,0) [0|6.5535] "V" Vector__XXX
'''


def test_constants_lists_extended_ids_and_a_values_list(tmp_path):
    mapping = '''primary: ORION_Pack
battery_state:
  voltage: ORION_Pack.pack_voltage
  cell_voltage: [ORION_Cells.cell_b, ORION_Cells.cell_a]
  capacity: 50
  power_supply_technology: LIFE
  power_supply_health: GOOD
diagnostics:
  values: [ORION_Pack.pack_voltage, ORION_Cells]
'''
    device = make(tmp_path, mapping, EXTENDED_DBC)
    # 2566869221 = 0x80000000 | 0x18FF50E5: the DBC's mark of a 29-bit ID
    assert device.frame_ids == {(0x18FF50E5, True), (1712, False)}
    device.handle_frame(1712, bytes.fromhex('A08C7C92'), 1.0)  # 36000, 37500 x 0.1 mV
    assert device.handle_frame(0x18FF50E5, bytes.fromhex('0000E80F'), 2.0)  # 4072 x 0.1 V
    report = device.battery_report()
    assert report.voltage == pytest.approx(407.2)
    assert report.cell_voltage == pytest.approx([3.75, 3.6])  # the list's order
    assert report.capacity == 50.0 and report.power_supply_technology == 4  # LIFE
    assert report.power_supply_health == PowerSupplyHealth.GOOD
    values = device.diagnostic_report().values
    assert set(values) >= {'ORION_Pack.pack_voltage [V]', 'ORION_Cells.cell_a [V]',
                           'ORION_Cells.cell_b [V]'}
    assert 'ORION_Pack.pack_dcl [A]' not in values  # not in the list


FALLBACK_DBC = '''VERSION ""

BS_:

BU_: BMS

BO_ 300 PACK: 8 BMS
 SG_ voltage : 0|32@1- (1,0) [0|1000] "V" Vector__XXX
 SG_ current : 32|32@1- (1,0) [-500|500] "A" Vector__XXX

BO_ 301 CELLS: 4 BMS
 SG_ outer M : 0|8@1+ (1,0) [0|1] "" Vector__XXX
 SG_ inner m0M : 8|8@1+ (1,0) [0|1] "" Vector__XXX
 SG_ cell_0 m0 : 16|16@1+ (1,0) [0|5000] "mV" Vector__XXX
 SG_ cell_1 m1 : 16|16@1+ (1,0) [0|5000] "mV" Vector__XXX

SIG_VALTYPE_ 300 voltage : 1;
SIG_VALTYPE_ 300 current : 1;
SG_MUL_VAL_ 301 inner outer 0-0;
SG_MUL_VAL_ 301 cell_0 inner 0-0;
SG_MUL_VAL_ 301 cell_1 inner 1-1;
'''


def test_float_signals_and_nested_multiplexing_decode_through_cantools(tmp_path):
    import struct
    mapping = ('primary: PACK\nbattery_state:\n  voltage: PACK.voltage\n'
               '  current: PACK.current\n'
               '  cell_voltage: {signal: "CELLS.cell_{i}", count: 2}\n')
    device = make(tmp_path, mapping, FALLBACK_DBC)
    assert [m.compiled for m in device.plan.messages] == [False, False]
    device.handle_frame(301, bytes([0, 0]) + (3700).to_bytes(2, 'little'), 1.0)
    device.handle_frame(301, bytes([0, 1]) + (3650).to_bytes(2, 'little'), 1.0)
    assert device.handle_frame(300, struct.pack('<ff', 398.5, -12.25), 1.0)
    report = device.battery_report()
    assert (report.voltage, report.current) == (398.5, -12.25)
    assert report.cell_voltage == pytest.approx([3.7, 3.65])  # both branches kept
    device.handle_frame(300, struct.pack('<ff', 1200.0, 0.0), 2.0)  # above [0|1000]
    assert math.isnan(device.battery_report().voltage) and device.frames_malformed == 1


def test_a_message_without_signals_compiles_to_an_empty_decoder():
    # msg_defs/bms16.dbc's BMS16_PowerOff is a command with no data: its generated decoder
    # once read `return (,), bad`, a SyntaxError when compiled.
    message = cantools.database.load_file(
        str(Path(__file__).parents[1] / 'msg_defs' / 'bms16.dbc')).get_message_by_name(
            'BMS16_PowerOff')
    compiled = dbc_codec.compile_message(message)
    assert compiled.compiled and compiled.decode_values(b'') == ((), [])
