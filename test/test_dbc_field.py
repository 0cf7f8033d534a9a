# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The dbc device on the DBC files and traces the field really has (test/fixtures/*/README.md).

foxBMS 2's own public trace through the shipped profile gives the values foxBMS's own test
states; a real Orion BMS 2 capture through the Orion profile gives the values written by hand
from its bytes; an export in the Orion utility's style (duplicated ``Blank`` signals, which
cantools' strict load refuses) loads and publishes the SoC as 0..1; a community vehicle DBC
with one broken, unrelated message (commaai/opendbc vw_mqb.dbc) works and names it.
"""
from __future__ import annotations

import math
from pathlib import Path

import can
import cantools
import pytest

from ams_can_bridge.devices.base import Level, PowerSupplyHealth
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.protocols.dbc_profiles import profile_files, PROFILES
from helpers import Clock

FIXTURES = Path(__file__).resolve().parent / 'fixtures'
FOXBMS_TRACE = FIXTURES / 'foxbms2' / 'can-log.trc'
ORION_CAPTURE = FIXTURES / 'orion_bms2' / 'we_ev_orion_capture.log'
ORION_EXPORT = FIXTURES / 'orion_bms2' / 'orion_export_style.dbc'
VW_MQB = FIXTURES / 'opendbc' / 'vw_mqb.dbc'


def replay(device: DbcDevice, clock: Clock, log: Path, until: int | None = None) -> int:
    """Feed a log's frames at their own times; return how many were primary frames."""
    primaries = 0
    with can.LogReader(str(log)) as reader:
        for msg in reader:
            clock.now = msg.timestamp
            primaries += device.handle_frame(msg.arbitration_id, bytes(msg.data), clock.now)
            if until is not None and msg.arbitration_id == until:
                break
    return primaries


def first_stamp(log: Path) -> float:
    with can.LogReader(str(log)) as reader:
        return next(iter(reader)).timestamp


# --- foxBMS 2 --------------------------------------------------------------------------------
def test_every_profile_is_found_and_loads_strictly_or_says_why():
    for name in PROFILES:
        dbc, mapping = profile_files(name)
        assert dbc.is_file() and mapping.is_file()
        assert DbcDevice('pack', {'profile': name}, Clock()).start_log()[1] == [], name


def test_foxbms2_trace_through_the_profile_gives_the_values_foxbms_states():
    clock = Clock(first_stamp(FOXBMS_TRACE))
    device = DbcDevice('pack', {'profile': 'foxbms2'}, clock)
    assert replay(device, clock, FOXBMS_TRACE) == 1  # one f_BmsState (0x220) in the trace
    values = device.diagnostic_report().values
    # tests/fox-cmds/etl/test_fox_etl.py EXPECTED_OUTPUTS, 0x243 and 0x241 (String0)
    assert values['f_StringValuesP0.Voltage [V]'] == '63.93'
    assert values['f_StringValuesP0.Current [A]'] == '0'
    assert values['f_StringValuesP0.Power [kW]'] == '0'
    assert values['f_StringMinMaxCellTemperature.MaximumCellTemperature [degC]'] == '62'
    assert values['f_StringMinMaxCellTemperature.MinimumCellTemperature [degC]'] == '-47.5'
    # ... and its indices (the profile's DBC gives those 4-bit signals their whole range)
    assert values['f_StringMinMaxCellTemperature.SensorMaximumCellTemperature'] == '15'
    assert values['f_StringMinMaxCellTemperature.SensorMinimumCellTemperature'] == '1'
    # 0x220 03 08 ...: BmsState ERROR, GeneralError 1 "Error"
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR and diag.message.startswith('foxBMS in ERROR (10)')
    report = device.battery_report()
    assert report.present and report.power_supply_health == PowerSupplyHealth.UNSPEC_FAILURE
    # 0x250 mux 2 carries cells 8..11 (1996, 2005, 2001, 1999 mV) flagged 0 "Invalid"
    assert all(math.isnan(v) for v in report.cell_voltage[8:12])
    # ... as are the temperatures 6..11 of 0x260 mux 1: both frames count as malformed
    assert all(math.isnan(v) for v in report.cell_temperature[6:8])
    assert device.frames_malformed == 2 and 'flagged invalid' in device.last_malformed


def test_foxbms2_a_cell_flagged_1_valid_is_read_and_0_invalid_is_not():
    # src/app/driver/can/cbs/tx-cyclic/can_cbs_tx_f_cell-voltages.c: signalDataIsValid = 1u
    # for a valid cell (its unit test: cell 0 valid sets bit 12 to 1, cell 1 invalid bit 13
    # to 0). Written by hand from foxbms.dbc: mux 0 in byte 0; flags bits 12, 13 = byte 1
    # bits 4, 5; CellVoltage_000 11|13@0 = 3700 mV: byte 1 bits 3..0 = 0x7, byte 2 = 0x3A,
    # byte 3 bit 7 = 0; CellVoltage_001 30|13@0 = 3701 mV: byte 3 bits 6..0 = 0x39, byte 4
    # bits 7..2 = 0b110101 (0xD4)
    frame = bytes.fromhex('00173A39D4000000')
    dbc, _ = profile_files('foxbms2')
    decoded = cantools.database.load_file(str(dbc)).decode_message(0x250, frame)
    assert (decoded['CellVoltage_000'], decoded['CellVoltage_001']) == (3700, 3701)
    clock = Clock(0.0)
    device = DbcDevice('pack', {'profile': 'foxbms2'}, clock)
    device.handle_frame(0x250, frame, 0.0)
    device.handle_frame(0x220, bytes(8), 0.0)
    cells = device.battery_report().cell_voltage
    assert cells[0] == pytest.approx(3.700) and math.isnan(cells[1])


# --- Orion BMS 2 -----------------------------------------------------------------------------
def test_orion_capture_through_the_profile_gives_the_values_of_its_bytes():
    clock = Clock(first_stamp(ORION_CAPTURE))
    device = DbcDevice('pack', {'profile': 'orion_bms2'}, clock)
    assert replay(device, clock, ORION_CAPTURE, until=0x6B1) == 1
    report = device.battery_report()
    # 0x6B0 00 00 0B 08 A1 01 62 CF: 0 A, 0x0B08 x 0.1 = 282.4 V, 0xA1 x 0.5 = 80.5 %
    assert report.voltage == pytest.approx(282.4) and report.current == 0.0
    assert report.percentage == pytest.approx(0.805)
    # 0x6B1 00 12 00 04 14 11 00 F4: High_Temperature 0x14 = 20 degC
    assert report.temperature == 20.0
    values = device.diagnostic_report().values
    assert values['MSGID_0X6B1.Pack_CCL [Amps]'] == '4'  # = 0x6B3's Pack_CCL, same moment
    assert values['MSGID_0X6B1.Pack_DCL [Amps]'] == '18'
    assert values['MSGID_0X6B0.Relay_State'] == '354'  # 0x0162: no malfunction bit (0x08)
    assert device.diagnostic_report().level == Level.OK


def test_orion_style_export_with_duplicate_blanks_loads_and_publishes_soc_as_a_fraction(
        tmp_path):
    mapping = tmp_path / 'orion.yaml'
    mapping.write_text('primary: MSGID_0X6B0\n'
                       'battery_state:\n'
                       '  voltage: MSGID_0X6B0.Pack_Inst_Voltage\n'
                       '  percentage: MSGID_0X6B0.Pack_SOC\n'
                       '  temperature: MSGID_0X6B1.High_Temperature\n'
                       '  charge: MSGID_0X355.Adaptive_Total_Capacity\n')
    with pytest.raises(Exception, match='overlapping'):
        cantools.database.load_file(str(ORION_EXPORT), strict=True)
    clock = Clock(first_stamp(ORION_CAPTURE))
    device = DbcDevice('pack', {'dbc_file': str(ORION_EXPORT), 'mapping_file': str(mapping)},
                       clock)
    replay(device, clock, ORION_CAPTURE, until=0x6B1)
    report = device.battery_report()
    assert report.percentage == pytest.approx(0.805)  # "Percent" -> 0..1, not 80.5
    assert report.voltage == pytest.approx(282.4) and report.temperature == 20.0
    assert report.charge == pytest.approx(156.0)  # 0x355 bytes 6-7 0x0618 x 0.1 "Amphours"
    notes = device.start_log()[1]
    assert any('MSGID_0X6B1 has duplicated signal names Blank (x2)' in n for n in notes)
    diag = device.diagnostic_report()
    # three unmapped messages with duplicated names: said at start, not a lasting WARN
    assert diag.level == Level.OK and diag.message == 'OK', diag.message
    assert 'MSGID_0X6B3 has duplicated signal names Blank' in ' '.join(diag.values.values())
    # a duplicated name cannot be mapped: stop, naming it and its message
    mapping.write_text(mapping.read_text() + 'diagnostics:\n  values: [MSGID_0X6B3.Blank]\n')
    with pytest.raises(ValueError, match='signal Blank appears 2 times in message '
                                         'MSGID_0X6B3'):
        DbcDevice('pack', {'dbc_file': str(ORION_EXPORT), 'mapping_file': str(mapping)},
                  Clock())


# --- a community vehicle DBC -----------------------------------------------------------------
VW_MAPPING = '''primary: BMS_Hybrid_01
battery_state:
  voltage: BMS_Hybrid_01.BMS_IstSpannung_HV       # Unit_Volt
  temperature: BMS_Hybrid_01.BMS_Temperatur       # Unit_DegreCelsi
'''


def test_community_dbc_with_one_broken_unrelated_message_works_and_names_it(tmp_path):
    with pytest.raises(Exception, match='PLA_Bremsverzoegerung and PLA_Bremsmoment'):
        cantools.database.load_file(str(VW_MQB), strict=True)
    mapping = tmp_path / 'vw.yaml'
    mapping.write_text(VW_MAPPING)
    device = DbcDevice('pack', {'dbc_file': str(VW_MQB), 'mapping_file': str(mapping)},
                       Clock(0.0))
    assert device.start_log()[1] == [
        'DBC message PLA_01 is broken and unusable: The signals PLA_Bremsverzoegerung and '
        'PLA_Bremsmoment are overlapping']
    assert device.warnings == []  # both units known: Unit_Volt, Unit_DegreCelsi
    # written by hand from the DBC (0x65C, little endian): BMS_Temperatur 40|8 (0.5,-40):
    # byte 5 = 0x82 = 130 -> 25 degC; BMS_IstSpannung_HV 56|8 (1,100): byte 7 = 0xC8 -> 300 V
    assert device.handle_frame(0x65C, bytes.fromhex('00000000008200C8'), 1.0)
    report = device.battery_report()
    assert report.voltage == 300.0 and report.temperature == 25.0
    diag = device.diagnostic_report()  # PLA_01 is not mapped: said at start, no WARN
    assert diag.level == Level.OK and diag.message == 'OK', diag.message
    assert 'PLA_01 is broken' in diag.values['DBC note 1']
    mapping.write_text(VW_MAPPING + 'diagnostics:\n  values: [PLA_01.PLA_Bremsmoment]\n')
    with pytest.raises(ValueError) as info:
        DbcDevice('pack', {'dbc_file': str(VW_MQB), 'mapping_file': str(mapping)}, Clock())
    assert 'message PLA_01 is broken in the DBC (The signals PLA_Bremsverzoegerung and ' \
        'PLA_Bremsmoment are overlapping)' in str(info.value)
