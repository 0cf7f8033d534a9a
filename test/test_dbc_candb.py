# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
CANdb++ exports and DBC encodings as real files have them (issue 35, points 4 and 10).

test/fixtures/candb_export.dbc is hand-written in the shape of real CANdb++ exports (its
network comment names them): Vector's placeholder message VECTOR__INDEPENDENT_SIG_MSG (ID
0xC0000000, DLC 0) with value tables of its signals, as a car's Orion export has 38 of them,
and "°C" in UTF-8 as the IVT-S vendor DBC writes it.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.protocols.dbc_load import read_dbc
from helpers import Clock

CANDB_EXPORT = Path(__file__).parent / 'fixtures' / 'candb_export.dbc'
MAPPING = '''primary: BmsPack
battery_state:
  voltage: BmsPack.PackVoltage
  current: BmsPack.PackCurrent
  percentage: BmsPack.PackSOC
  temperature: BmsPack.HighTemperature
'''
# BmsPack 0x6B0, little endian: 2926 x 0.1 = 292.6 V, 0 A, 167 x 0.5 = 83.5 %, 16 degC
FRAME = bytes([0x6E, 0x0B, 0x00, 0x00, 0xA7, 0x10, 0x00, 0x00])


def make(tmp_path: Path, dbc: Path = CANDB_EXPORT) -> DbcDevice:
    mapping = tmp_path / 'mapping.yaml'
    mapping.write_text(MAPPING)
    return DbcDevice('pack', {'dbc_file': str(dbc), 'mapping_file': str(mapping)}, Clock(0.0))


# --- 35.4: the placeholder message is not "no signal"; unused parts are no lasting level ----
def test_candb_placeholder_value_tables_are_said_once_as_info_not_warned(tmp_path):
    loaded = read_dbc(CANDB_EXPORT)
    assert loaded.strict and loaded.notes() == []  # nothing of it is broken
    device = make(tmp_path)
    info, warn = device.start_log()
    assert warn == []
    assert ("DBC: CANdb++'s placeholder message VECTOR__INDEPENDENT_SIG_MSG (ID 3221225472: "
            'signals in no message, never on the bus) left out with its 2 value table(s)'
            in info)
    assert device.handle_frame(0x6B0, FRAME, 1.0)
    report = device.battery_report()
    assert report.voltage == pytest.approx(292.6) and report.percentage == pytest.approx(0.835)
    diag = device.diagnostic_report()
    assert diag.level == Level.OK and diag.message == 'OK', diag.message


# --- 35.10: UTF-8 first, then cp1252 as CANdb++ writes ------------------------------------
def test_utf8_degree_sign_is_read_as_degrees(tmp_path):
    raw = CANDB_EXPORT.read_bytes()
    assert '°C'.encode('utf-8') in raw  # the file really is UTF-8
    loaded = read_dbc(CANDB_EXPORT)
    unit = loaded.db.get_message_by_name('BmsPack').get_signal_by_name('HighTemperature').unit
    assert unit == '°C'
    device = make(tmp_path)
    assert 'DBC read as UTF-8' in device.start_log()[0]
    assert device.warnings == []  # °C is a unit the rules know; Â°C would be guessed at
    device.handle_frame(0x6B0, FRAME, 1.0)
    assert device.battery_report().temperature == 16.0
    shown = device.diagnostic_report().values
    assert shown['BmsPack.HighTemperature [°C]'] == '16'
    assert not any('Â' in key for key in shown)


def test_cp1252_export_still_reads_its_degree_sign(tmp_path):
    cp1252 = tmp_path / 'candb_cp1252.dbc'
    cp1252.write_bytes(CANDB_EXPORT.read_bytes().decode('utf-8').encode('cp1252'))
    assert b'\xb0C' in cp1252.read_bytes()  # a lone 0xB0: not UTF-8
    loaded = read_dbc(cp1252)
    unit = loaded.db.get_message_by_name('BmsPack').get_signal_by_name('HighTemperature').unit
    assert unit == '°C'
    device = make(tmp_path, cp1252)
    assert 'DBC read as CP1252' in device.start_log()[0]
    device.handle_frame(0x6B0, FRAME, 1.0)
    assert device.battery_report().temperature == 16.0


def test_a_byte_cp1252_lacks_falls_back_to_latin_1(tmp_path):
    odd = tmp_path / 'odd.dbc'  # 0x81 is undefined in cp1252 and no UTF-8 on its own
    odd.write_bytes(CANDB_EXPORT.read_bytes().replace(b'Hand-written', b'Hand\x81written'))
    loaded = read_dbc(odd)
    assert loaded.db.get_message_by_name('BmsPack') is not None
    assert 'DBC read as LATIN-1' in loaded.info


def test_line_numbers_of_other_dropped_lines_stay_those_of_the_file(tmp_path):
    text = CANDB_EXPORT.read_bytes().decode('utf-8')
    text += 'VAL_ 1712 NoSuchSignal 1 "On" 0 "Off" ;\r\n'  # a table of no signal, after them
    odd = tmp_path / 'odd.dbc'
    odd.write_bytes(text.encode('utf-8'))
    line = text.splitlines().index('VAL_ 1712 NoSuchSignal 1 "On" 0 "Off" ;') + 1
    assert read_dbc(odd).notes() == [
        f'DBC line {line} dropped (value table of no signal): VAL_ 1712 NoSuchSignal 1 "On" '
        '0 "Off" ;']
