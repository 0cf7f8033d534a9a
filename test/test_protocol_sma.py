# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""SMA Sunny Island BMS codec: golden frames written by hand from doc/protocols.md section 5."""
from hypothesis import given, settings, strategies as st
import pytest

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import Frame, msg_defs_dir
from ams_can_bridge.protocols.sma import (
    SMA_CONDITIONS, SMA_IDS, SmaAlarms, SmaBattery, SmaBatteryInfo, SmaCodec, SmaFlag,
    SmaLimits, SmaManufacturer, SmaSoc)
from ams_can_bridge.protocols.sma_dialects import DIALECT_IDS
from helpers import assert_decodes_or_malformed, load_dbc_strictly

CODEC = SmaCodec()
DBC = str(msg_defs_dir() / 'sma.dbc')


def test_dbc_loads_strictly_in_cantools_and_canmatrix_without_warnings(caplog):
    db, matrix = load_dbc_strictly(DBC, caplog)
    assert {m.frame_id for m in db.messages} == set(SMA_IDS) | set(DIALECT_IDS)
    assert len(matrix.frames) == 19
    flags = db.get_message_by_frame_id(0x35A)
    assert len(flags.signals) == 32
    assert flags.get_signal_by_name('Warning_CellImbalance').choices == {
        0: 'Not supported', 1: 'Active', 2: 'OK', 3: 'Not supported'}


def test_ids_are_fixed():
    assert CODEC.arbitration_ids == {0x351, 0x355, 0x356, 0x35A, 0x35E, 0x35F,
                                     0x359, 0x35C, *range(0x370, 0x37A), 0x382}


def test_limits_golden():
    # 552 x 0.1 V, 500 x 0.1 A, 1000 x 0.1 A (0x03E8), 480 x 0.1 V
    data = bytes([0x28, 0x02, 0xF4, 0x01, 0xE8, 0x03, 0xE0, 0x01])
    limits = CODEC.decode(0x351, data)
    assert limits == SmaLimits(55.2, 50.0, 100.0, 48.0)
    assert CODEC.encode(limits) == Frame(0x351, data)
    # a limit is a magnitude: -1000 x 0.1 A (0xFC18) is malformed (section 5.2)
    with pytest.raises(MalformedFrameError, match='discharge current limit -100 A is negative'):
        CODEC.decode(0x351, data[:4] + bytes([0x18, 0xFC]) + data[6:])


def test_limits_invalid_markers_and_short_frame():
    data = bytes([0xFF, 0xFF, 0x00, 0x80, 0x00, 0x80, 0xFF, 0xFF])
    limits = CODEC.decode(0x351, data)
    assert limits == SmaLimits(None, None, None, None)
    assert CODEC.encode(limits).data == data
    # DLC 6: no discharge voltage limit sent
    assert CODEC.decode(0x351, data[:6]).discharge_voltage_v is None
    # 0x7FFF and 0xFFFE are real values, not markers
    edge = CODEC.decode(0x351, bytes([0xFE, 0xFF, 0xFF, 0x7F, 0xFF, 0x7F, 0, 0]))
    assert edge == SmaLimits(6553.4, 3276.7, 3276.7, None)  # 0 V = no limit (section 5)


def test_soc_golden_with_and_without_high_resolution():
    assert CODEC.decode(0x355, bytes([0x50, 0x00, 0x64, 0x00])) == SmaSoc(80, 100, None)
    data = bytes([0x50, 0x00, 0x63, 0x00, 0x13, 0x1F])  # 7955 x 0.01 %
    soc = CODEC.decode(0x355, data)
    assert soc == SmaSoc(80, 99, 79.55)
    assert CODEC.encode(soc) == Frame(0x355, data)
    assert CODEC.decode(0x355, data + b'\x00\x00') == soc  # DLC 8 padding
    none = CODEC.decode(0x355, bytes([0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]))
    assert none == SmaSoc(None, None, None)
    # No high-resolution SoC: always sent as the 0xFFFF marker in a 6-byte frame.
    assert CODEC.encode(SmaSoc(80, 100)).data == bytes([0x50, 0, 0x64, 0, 0xFF, 0xFF])


def test_battery_golden_sign_is_charge_positive():
    # 5123 x 0.01 V, -125 x 0.1 A (0xFF83: discharging 12.5 A), 253 x 0.1 degC
    data = bytes([0x03, 0x14, 0x83, 0xFF, 0xFD, 0x00])
    battery = CODEC.decode(0x356, data)
    assert battery == SmaBattery(51.23, -12.5, 25.3)
    assert CODEC.encode(battery) == Frame(0x356, data)
    # negative temperature: -105 = 0xFF97
    cold = CODEC.decode(0x356, bytes([0, 0, 0x7D, 0, 0x97, 0xFF]))
    assert cold == SmaBattery(0.0, 12.5, -10.5)


def test_battery_invalid_markers():
    data = bytes([0x00, 0x80, 0x00, 0x80, 0x00, 0x80])
    assert CODEC.decode(0x356, data) == SmaBattery(None, None, None)
    assert CODEC.encode(SmaBattery(None, None, None)).data == data


@pytest.mark.parametrize('index', range(16))
@pytest.mark.parametrize('kind', ['alarms', 'warnings'])
@pytest.mark.parametrize('raw, flag', [(0, SmaFlag.NOT_SUPPORTED), (1, SmaFlag.ACTIVE),
                                       (2, SmaFlag.OK), (3, SmaFlag.NOT_SUPPORTED)])
def test_every_flag_pair(index, kind, raw, flag):
    if kind == 'warnings' and index == 13:
        return  # byte 7 bits 2-3: the online status (test_online_status_pair)
    data = bytearray(8)
    byte = index // 4 + (4 if kind == 'warnings' else 0)
    data[byte] = raw << (2 * (index % 4))
    decoded = CODEC.decode(0x35A, bytes(data))
    name = SMA_CONDITIONS[index]
    assert getattr(decoded, kind)[name] is flag
    other = 'warnings' if kind == 'alarms' else 'alarms'
    assert set(getattr(decoded, other).values()) == {SmaFlag.NOT_SUPPORTED}
    assert [n for n, f in getattr(decoded, kind).items() if f != SmaFlag.NOT_SUPPORTED] == (
        [name] if raw in (1, 2) else [])
    if raw != 3:  # 3 decodes as NOT_SUPPORTED and is sent back as 0
        assert CODEC.encode(decoded).data == bytes(data)


def test_flag_condition_names_in_protocol_order():
    assert SMA_CONDITIONS == (
        'general', 'high_voltage', 'low_voltage', 'high_temperature', 'low_temperature',
        'high_temperature_charge', 'low_temperature_charge', 'high_discharge_current',
        'high_charge_current', 'contactor', 'short_circuit', 'bms_internal',
        'cell_imbalance', 'reserved1', 'reserved2', 'generator')
    assert [(f.name, f.value) for f in SmaFlag] == [
        ('NOT_SUPPORTED', 0), ('ACTIVE', 1), ('OK', 2)]


def test_bms16_style_flags():
    # BMS16 seed: byte 0 bit 2 overvoltage, bit 5 no undervoltage, bit 7 temperature OK;
    # byte 1 bit 6 overcurrent detected.
    flags = CODEC.decode(0x35A, bytes([0b1010_0100, 0b0100_0000, 0, 0, 0, 0, 0, 0]))
    assert flags.active_alarms == ('high_voltage', 'high_discharge_current')
    assert flags.alarms['low_voltage'] is SmaFlag.OK
    assert flags.alarms['high_temperature'] is SmaFlag.OK
    assert flags.active_warnings == ()
    # A 2-byte frame is accepted: the bytes not sent are not supported.
    assert CODEC.decode(0x35A, bytes([0b1010_0100, 0b0100_0000])) == flags


def test_flags_encoder_refuses_unknown_names_and_values():
    with pytest.raises(EncodeRangeError, match='sma.alarms'):
        SmaAlarms({'overvoltage': SmaFlag.ACTIVE})
    with pytest.raises(EncodeRangeError, match='sma.warnings.general'):
        CODEC.encode(SmaAlarms(warnings={'general': 3}))


def test_manufacturer_golden():
    assert CODEC.decode(0x35E, b'PYLON   ') == SmaManufacturer('PYLON')
    assert CODEC.decode(0x35E, b'BYD') == SmaManufacturer('BYD')
    assert CODEC.decode(0x35E, b'SIM\x00\x00\x00\x00\x00') == SmaManufacturer('SIM')
    assert CODEC.decode(0x35E, b'A\xffB\x01') == SmaManufacturer('A?B?')
    assert CODEC.encode(SmaManufacturer('SIMBMS')) == Frame(0x35E, b'SIMBMS\x00\x00')
    for bad in ('', 'NINE CHAR', 'Größe'):
        with pytest.raises(EncodeRangeError, match='sma.manufacturer'):
            CODEC.encode(SmaManufacturer(bad))


def test_battery_info_golden():
    data = bytes([0x01, 0x00, 0x02, 0x01, 0xC8, 0x00])
    info = CODEC.decode(0x35F, data)
    assert info == SmaBatteryInfo(1, 0x0102, 200)
    assert CODEC.encode(info) == Frame(0x35F, data)
    assert CODEC.decode(0x35F, bytes([0xFF] * 8)) == SmaBatteryInfo(None, None, None)


@pytest.mark.parametrize('frame_id, bad_dlcs', [
    (0x351, (0, 5)), (0x355, (0, 3)), (0x356, (0, 5)), (0x35A, (0,)), (0x35E, (0,)),
    (0x35F, (0, 5))])
def test_wrong_dlc_is_malformed(frame_id, bad_dlcs):
    for dlc in bad_dlcs:
        with pytest.raises(MalformedFrameError, match=f'DLC {dlc}'):
            CODEC.decode(frame_id, bytes(dlc))


def test_foreign_id_is_malformed():
    with pytest.raises(MalformedFrameError, match='not an SMA'):
        CODEC.decode(0x352, bytes(8))


def test_encoders_refuse_what_the_wire_cannot_carry():
    with pytest.raises(EncodeRangeError, match='sma.charge_voltage_v'):
        CODEC.encode(SmaLimits(-1.0, 0.0, 0.0, 0.0))
    with pytest.raises(EncodeRangeError, match='sma.current_a'):
        CODEC.encode(SmaBattery(50.0, 4000.0, 20.0))
    with pytest.raises(EncodeRangeError, match='sma.soc_pct'):
        CODEC.encode(SmaSoc(101, 100))
    with pytest.raises(EncodeRangeError, match='sma.voltage_v'):
        CODEC.encode(SmaBattery(float('nan'), 0.0, 20.0))


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(sorted(SMA_IDS | DIALECT_IDS)), st.binary(max_size=8))
def test_any_frame_decodes_or_is_malformed(frame_id, data):
    assert_decodes_or_malformed(CODEC, frame_id, data)


def _field(data, first):
    return int.from_bytes(data[first:first + 2], 'little', signed=True)


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=8, max_size=8))
def test_limits_and_battery_round_trip(data):
    if any(-0x8000 < _field(data, k) < 0 for k in (2, 4)):  # a negative current limit
        with pytest.raises(MalformedFrameError, match='is negative'):
            CODEC.decode(0x351, data)
    elif data[6:8] == bytes(2):  # 0 V discharge limit = none: sent back as the 0xFFFF marker
        assert CODEC.encode(CODEC.decode(0x351, data)).data == data[:6] + b'\xff\xff'
    else:
        assert CODEC.encode(CODEC.decode(0x351, data)).data == data
    voltage, temperature = _field(data, 0), _field(data, 4)
    if -0x8000 < voltage < 0:  # a negative pack voltage: no reading
        with pytest.raises(MalformedFrameError, match='pack voltage .* is negative'):
            CODEC.decode(0x356, data[:6])
    elif temperature != -0x8000 and not -2731.5 <= temperature <= 2000:  # no battery's
        with pytest.raises(MalformedFrameError, match='outside -273.15..200 degC'):
            CODEC.decode(0x356, data[:6])
    else:
        assert CODEC.encode(CODEC.decode(0x356, data[:6])).data == data[:6]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from([0, 1, 2]), min_size=32, max_size=32))
def test_flags_round_trip(pairs):
    data = bytearray(8)
    for k, raw in enumerate(pairs):
        data[k // 4] |= raw << (2 * (k % 4))
    assert CODEC.encode(CODEC.decode(0x35A, bytes(data))).data == bytes(data)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 100) | st.none(), st.integers(0, 100) | st.none(),
       st.integers(0, 10000).map(lambda n: n / 100) | st.none())
def test_soc_round_trip(soc, soh, hires):
    message = SmaSoc(soc, soh, hires)
    assert CODEC.decode(0x355, CODEC.encode(message).data) == message


@pytest.mark.parametrize('data, reason', [
    (bytes([101, 0, 100, 0]), 'SoC 101 % is above 100 %'),
    (bytes([50, 0, 100, 0, 0x11, 0x27]), 'high-resolution SoC 100.01 % is above 100 %'),
])
def test_a_state_of_charge_above_100_percent_is_malformed(data, reason):
    with pytest.raises(MalformedFrameError, match=reason):
        CODEC.decode(0x355, data)
    assert CODEC.decode(0x355, bytes([100, 0, 100, 0, 0x10, 0x27])).soc_hires_pct == 100.0


def test_a_temperature_below_absolute_zero_is_malformed():
    with pytest.raises(MalformedFrameError, match='-273.2 degC is outside -273.15..200 degC'):
        CODEC.decode(0x356, bytes([0, 0, 0, 0]) + (-2732).to_bytes(2, 'little', signed=True))
    reading = CODEC.decode(0x356, bytes([0, 0, 0, 0]) + (-2731).to_bytes(2, 'little',
                                                                         signed=True))
    assert reading.temperature_c == pytest.approx(-273.1)
