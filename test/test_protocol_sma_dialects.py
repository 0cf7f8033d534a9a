# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Pylontech (0x359, 0x35C) and Victron (0x370..0x377) frames of the SMA protocol family.

Golden frames written by hand from the facts of issue 10 (bit numbers, byte order, units),
not produced by the encoder; the encoder and msg_defs/sma.dbc are then checked against them.
"""
from hypothesis import given, settings, strategies as st
import pytest

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.common import msg_defs_dir
from ams_can_bridge.protocols.sma import SMA_CONDITIONS, SmaCodec
from ams_can_bridge.protocols.sma_dialects import (
    PYLONTECH_CONDITION_NAMES, PylontechAlarms, PylontechRequest, VictronBmsName,
    VictronCellExtremes, VictronCellId, VictronModules)
from helpers import load_dbc_strictly

CODEC = SmaCodec()

# 0x359: byte 0 = over-voltage (bit 1) + discharge over-current (bit 7); byte 1 = charge
# over-current (bit 0) + BMS internal (bit 3); byte 2 = warnings under-voltage (bit 2) +
# under-temperature (bit 4); byte 3 none; byte 4 = 3 modules.
PYLON_GOLDEN = bytes([0b1000_0010, 0b0000_1001, 0b0001_0100, 0x00, 0x03, 0, 0, 0])
# 0x373: 3300 mV, 3312 mV, 288 K, 300 K, each U16 little-endian
CELLS_GOLDEN = bytes([0xE4, 0x0C, 0xF0, 0x0C, 0x20, 0x01, 0x2C, 0x01])


def test_pylontech_alarms_golden():
    reading = CODEC.decode(0x359, PYLON_GOLDEN)
    assert reading == PylontechAlarms(
        frozenset({'high_voltage', 'high_discharge_current', 'high_charge_current',
                   'bms_internal'}),
        frozenset({'low_voltage', 'low_temperature'}), 3)
    assert reading.active_alarms == ('high_voltage', 'high_discharge_current',
                                     'high_charge_current', 'bms_internal')
    assert reading.active_warnings == ('low_voltage', 'low_temperature')
    assert CODEC.encode(reading) == Frame(0x359, PYLON_GOLDEN)


@pytest.mark.parametrize('byte, bit, name', [
    (0, 1, 'high_voltage'), (0, 2, 'low_voltage'), (0, 3, 'high_temperature'),
    (0, 4, 'low_temperature'), (0, 7, 'high_discharge_current'),
    (1, 0, 'high_charge_current'), (1, 3, 'bms_internal')])
def test_pylontech_each_bit_alarm_and_warning(byte, bit, name):
    assert name in SMA_CONDITIONS  # same meaning as the 0x35A condition of that name
    alarm = bytearray(5)
    alarm[byte] = 1 << bit
    assert CODEC.decode(0x359, bytes(alarm)) == PylontechAlarms(
        frozenset({name}), frozenset(), 0)
    warning = bytearray(5)
    warning[byte + 2] = 1 << bit
    assert CODEC.decode(0x359, bytes(warning)) == PylontechAlarms(
        frozenset(), frozenset({name}), 0)


def test_pylontech_undefined_bits_and_short_frames():
    # bits 0, 5, 6 of byte 0 and 1, 2, 4..7 of byte 1 mean nothing in this dialect
    undefined = bytes([0b0110_0001, 0b1111_0110, 0b0110_0001, 0b1111_0110, 1])
    assert CODEC.decode(0x359, undefined) == PylontechAlarms(frozenset(), frozenset(), 1)
    assert CODEC.decode(0x359, PYLON_GOLDEN[:4]).module_count is None  # DLC 4: not sent
    for dlc in (0, 3):
        with pytest.raises(MalformedFrameError, match=f'DLC {dlc}'):
            CODEC.decode(0x359, PYLON_GOLDEN[:dlc])


@pytest.mark.parametrize('byte0, charge, discharge, asks', [
    (0b1100_0000, True, True, False), (0b1000_0000, True, False, False),
    (0b0100_0000, False, True, False), (0b0010_0000, False, False, True),
    (0b0000_0111, False, False, False)])
def test_pylontech_request_golden(byte0, charge, discharge, asks):
    reading = CODEC.decode(0x35C, bytes([byte0, 0x00]))
    assert reading == PylontechRequest(charge, discharge, asks)
    assert CODEC.decode(0x35C, bytes([byte0])) == reading  # DLC 1 is enough
    if not byte0 & 0x07:
        assert CODEC.encode(reading) == Frame(0x35C, bytes([byte0, 0x00]))
    with pytest.raises(MalformedFrameError, match='DLC 0'):
        CODEC.decode(0x35C, b'')


def test_victron_name_and_cell_ids_golden():
    assert CODEC.decode(0x370, b'SIMBMS 1') == VictronBmsName(1, 'SIMBMS 1')
    assert CODEC.decode(0x371, b'6S LFP\x00\x00') == VictronBmsName(2, '6S LFP')
    assert CODEC.encode(VictronBmsName(2, '6S LFP')) == Frame(0x371, b'6S LFP\x00\x00')
    assert CODEC.decode(0x374, b'C3') == VictronCellId('min_voltage', 'C3')
    assert CODEC.decode(0x375, b'C11     ') == VictronCellId('max_voltage', 'C11')
    assert CODEC.decode(0x376, b'T1\x00') == VictronCellId('min_temperature', 'T1')
    assert CODEC.decode(0x377, b'M2T\xff') == VictronCellId('max_temperature', 'M2T?')
    assert CODEC.encode(VictronCellId('max_temperature', 'T2')) == Frame(
        0x377, b'T2\x00\x00\x00\x00\x00\x00')
    with pytest.raises(EncodeRangeError, match='bms_name'):
        CODEC.encode(VictronBmsName(1, 'NINE CHAR'))


def test_victron_modules_golden():
    data = bytes([0x04, 0x00, 0x01, 0x00, 0x00, 0x00, 0x02, 0x00])
    reading = CODEC.decode(0x372, data)
    assert reading == VictronModules(ok=4, blocking_charge=1, blocking_discharge=0, offline=2)
    assert CODEC.encode(reading) == Frame(0x372, data)
    assert CODEC.decode(0x372, bytes([0x01, 0x01] + [0xFF] * 6)) == VictronModules(
        257, None, None, None)
    with pytest.raises(MalformedFrameError, match='DLC 7'):
        CODEC.decode(0x372, data[:7])


def test_victron_cell_extremes_golden():
    reading = CODEC.decode(0x373, CELLS_GOLDEN)
    assert reading == VictronCellExtremes(3.3, 3.312, 288, 300)
    assert reading.min_temperature_c == 14.85 and reading.max_temperature_c == 26.85
    assert CODEC.encode(reading) == Frame(0x373, CELLS_GOLDEN)
    unknown = CODEC.decode(0x373, bytes([0xFF] * 8))
    assert unknown == VictronCellExtremes(None, None, None, None)
    assert unknown.max_temperature_c is None


def test_victron_impossible_extremes_are_malformed():
    swapped_volts = CELLS_GOLDEN[2:4] + CELLS_GOLDEN[0:2] + CELLS_GOLDEN[4:]
    with pytest.raises(MalformedFrameError, match='min cell 3312 mV above max cell 3300'):
        CODEC.decode(0x373, swapped_volts)
    swapped_temps = CELLS_GOLDEN[:4] + CELLS_GOLDEN[6:8] + CELLS_GOLDEN[4:6]
    with pytest.raises(MalformedFrameError, match='300 K above max 288 K'):
        CODEC.decode(0x373, swapped_temps)
    with pytest.raises(MalformedFrameError, match='DLC 6'):
        CODEC.decode(0x373, CELLS_GOLDEN[:6])
    # 473 K (199.85 degC) is the hottest a cell may read: no battery is hotter than 200 degC
    hottest = CELLS_GOLDEN[:6] + bytes([0xD9, 0x01])  # 0x01D9 = 473
    assert CODEC.decode(0x373, hottest).max_temperature_k == 473
    with pytest.raises(MalformedFrameError, match='474 K is above 473 K'):
        CODEC.decode(0x373, CELLS_GOLDEN[:6] + bytes([0xDA, 0x01]))
    with pytest.raises(EncodeRangeError, match='max_temperature_k'):
        CODEC.encode(VictronCellExtremes(3.3, 3.4, 290, 474))
    # no cell reads above 10 V: 10001 mV (0x2711) is malformed, 10000 mV is not
    assert CODEC.decode(0x373, CELLS_GOLDEN[:2] + bytes([0x10, 0x27]) + CELLS_GOLDEN[4:])
    with pytest.raises(MalformedFrameError, match='cell voltage 10.001 V is above 10 V'):
        CODEC.decode(0x373, CELLS_GOLDEN[:2] + bytes([0x11, 0x27]) + CELLS_GOLDEN[4:])


def test_encoders_refuse_what_the_wire_cannot_carry():
    with pytest.raises(EncodeRangeError, match='contactor'):
        CODEC.encode(PylontechAlarms(frozenset({'contactor'})))
    with pytest.raises(EncodeRangeError, match='min_cell_v'):
        CODEC.encode(VictronCellExtremes(70.0, 3.3, 290, 291))
    with pytest.raises(EncodeRangeError, match='kind'):
        CODEC.encode(VictronCellId('median', 'C1'))


def test_dbc_agrees_with_the_golden_frames(caplog):
    db, _ = load_dbc_strictly(str(msg_defs_dir() / 'sma.dbc'), caplog)
    pylon = db.decode_message(0x359, PYLON_GOLDEN, decode_choices=False)
    active = {k for k, v in pylon.items() if v == 1 and k != 'ModuleCount'}
    assert active == {'Alarm_OverVoltage', 'Alarm_DischargeOverCurrent',
                      'Alarm_ChargeOverCurrent', 'Alarm_BmsInternal',
                      'Warning_UnderVoltage', 'Warning_UnderTemperature'}
    assert pylon['ModuleCount'] == 3
    assert db.decode_message(0x35C, bytes([0b1010_0000, 0]), decode_choices=False) == {
        'ChargeEnable': 1, 'DischargeEnable': 0, 'RequestChargeImmediately': 1,
        'ForceChargeRequestII': 0, 'FullChargeRequest': 0}
    cells = db.decode_message(0x373, CELLS_GOLDEN)
    assert cells['MinCellVoltage'] == pytest.approx(3.3)
    assert cells['MaxCellVoltage'] == pytest.approx(3.312)
    assert (cells['LowestCellTemperature'], cells['HighestCellTemperature']) == (288, 300)
    modules = db.decode_message(0x372, bytes([4, 0, 1, 0, 0, 0, 2, 0]))
    assert modules == {'NumberOfModulesOk': 4, 'NumberOfModulesBlockingCharge': 1,
                       'NumberOfModulesBlockingDischarge': 0, 'NumberOfModulesOffline': 2}
    # the DBC's names for 0x359 bits, in the codec's condition order
    assert [s.name for s in db.get_message_by_frame_id(0x359).signals[:7]] == [
        'Alarm_OverVoltage', 'Alarm_UnderVoltage', 'Alarm_OverTemperature',
        'Alarm_UnderTemperature', 'Alarm_DischargeOverCurrent', 'Alarm_ChargeOverCurrent',
        'Alarm_BmsInternal']
    assert len(PYLONTECH_CONDITION_NAMES) == 7


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=8, max_size=8))
def test_modules_round_trip(data):
    assert CODEC.encode(CODEC.decode(0x372, data)).data == data


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=5, max_size=5))
def test_pylontech_defined_bits_round_trip(data):
    defined = bytes([data[0] & 0x9E, data[1] & 0x09, data[2] & 0x9E, data[3] & 0x09, data[4]])
    assert CODEC.encode(CODEC.decode(0x359, data)).data[:5] == defined
