# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ZEVA BMS16 codec: golden frames written by hand from doc/protocols.md section 4, both ways."""
import cantools
from hypothesis import given, settings, strategies as st
import pytest

from ams_can_bridge.protocols.bms16 import (
    AcknowledgeError, BMS16_WARNINGS, Bms16Cells, Bms16Codec, Bms16Settings, Bms16ConfigPart1,
    Bms16ConfigPart2, Bms16Error, Bms16Status, check_config_value, CONFIG_FIELDS, PowerOff,
    ResetSoc)
from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import Frame, msg_defs_dir
from helpers import assert_decodes_or_malformed, load_dbc_strictly

CODEC = Bms16Codec()
GOOD_CONFIG = dict(cells=16, pack_capacity_ah=100, soc_warning_pct=20, full_voltage_v=58,
                   warn_current_a=200, trip_current_a=300, temperature_limit_c=60,
                   min_cell_v=2.8, max_cell_v=3.65, hysteresis_v=0.1, balance_v=3.45,
                   shunt_size_a=200)
# cells 16, 10 x 10 Ah, 20 %, 58 V, 20 x 10 A, 30 x 10 A, 60 degC, 56 x 0.05 V
GOOD_504 = bytes([16, 10, 20, 58, 20, 30, 60, 56])
# 73 x 0.05 V = 3.65, 2 x 0.05 = 0.10, 69 x 0.05 = 3.45, shunt code 2 = 200 A
GOOD_505 = bytes([73, 2, 69, 2])


def test_dbc_loads_strictly_in_cantools_and_canmatrix_without_warnings(caplog):
    db, matrix = load_dbc_strictly(str(msg_defs_dir() / 'bms16.dbc'), caplog)
    assert sorted(m.frame_id for m in db.messages) == list(range(500, 509))
    assert len(matrix.frames) == 9
    assert db.get_message_by_frame_id(500).get_signal_by_name('Error').choices[3] == \
        'Charge disabled (overvoltage cell)'
    assert db.get_message_by_frame_id(505).get_signal_by_name('ShuntSize').choices[3] == '500 A'


def test_status_golden_decode_and_encode():
    # error 3, SoC 80 %, 528 x 0.1 V, 32768 + 16 (1.6 A discharge), 25 degC
    data = bytes([0x03, 0x50, 0x10, 0x02, 0x10, 0x80, 0x19])
    status = CODEC.decode(500, data)
    assert status == Bms16Status(Bms16Error.CHARGE_DISABLED_OVERVOLTAGE, 80, 52.8, 1.6, 25)
    assert CODEC.encode(status) == Frame(500, data)


@pytest.mark.parametrize('raw, amps', [  # the document's -1000..+1000 A (raw 22768..42768)
    (0x58F0, -1000.0), (0x7FFF, -0.1), (0x8000, 0.0), (0x8001, 0.1), (0xA710, 1000.0)])
def test_status_current_offset_edges(raw, amps):
    data = bytes([0, 50, 0, 0, raw & 0xFF, raw >> 8, 20])
    assert CODEC.decode(500, data).current_a == amps
    assert CODEC.encode(Bms16Status(Bms16Error.NONE, 50, 0.0, amps, 20)).data == data


def test_status_agrees_with_the_dbc():
    db = cantools.database.load_file(str(msg_defs_dir() / 'bms16.dbc'), strict=True)
    data = bytes([0x05, 0x64, 0x20, 0x03, 0xF0, 0x58, 0x78])  # the top of each range
    ours = CODEC.decode(500, data)
    theirs = db.decode_message(500, data, decode_choices=False)
    assert theirs['Error'] == ours.error == Bms16Error.OVERCURRENT_WARNING
    assert theirs['Voltage'] == pytest.approx(ours.voltage_v) == 80.0
    assert theirs['Current'] == pytest.approx(ours.current_a) == -1000.0
    assert theirs['Temperature'] == ours.temperature_c == 120


@pytest.mark.parametrize('error', list(Bms16Error))
def test_every_error_code(error):
    status = CODEC.decode(500, bytes([int(error), 0, 0, 0, 0, 0x80, 0]))
    assert status.error is error
    assert CODEC.encode(status).data[0] == int(error)


def test_error_enum_values_and_warnings():
    assert [(e.name, e.value) for e in Bms16Error] == [
        ('NONE', 0), ('CORRUPT_EEPROM', 1), ('LOAD_DISABLED_UNDERVOLTAGE', 2),
        ('CHARGE_DISABLED_OVERVOLTAGE', 3), ('LOW_SOC', 4), ('OVERCURRENT_WARNING', 5),
        ('OVERCURRENT_SHUTDOWN', 6), ('OVERTEMPERATURE', 7), ('CRITICAL_VOLTAGE', 8)]
    assert BMS16_WARNINGS == {4, 5}


def test_cells_ninth_bits_at_the_edges():
    # cell1 255 -> 2.55, cell2 0+256 -> 2.56, cell3 244+256 -> 5.00 (the document's top),
    # cell4 74, cell5 0, cell6 1; byte 6 = bits 1 and 2 (cells 2 and 3)
    data = bytes([0xFF, 0x00, 0xF4, 0x4A, 0x00, 0x01, 0b0000_0110])
    cells = CODEC.decode(501, data)
    assert cells == Bms16Cells(0, (2.55, 2.56, 5.0, 0.74, 0.0, 0.01))
    assert CODEC.encode(cells) == Frame(501, data)


def test_cells_second_frame_and_sixth_ninth_bit():
    data = bytes([0x4A, 0x4B, 0x4C, 0x4D, 0x4E, 0x00, 0b0010_0001])
    cells = CODEC.decode(502, data)
    assert cells == Bms16Cells(6, (3.30, 0.75, 0.76, 0.77, 0.78, 2.56))
    assert CODEC.encode(cells) == Frame(502, data)


def test_last_cell_frame_has_four_cells_and_ignores_unused_bits():
    data = bytes([0x4A, 0xF4, 0x00, 0x01, 0x00, 0x00, 0b0000_1110])
    cells = CODEC.decode(503, data)
    assert cells == Bms16Cells(12, (0.74, 5.0, 2.56, 2.57))
    assert CODEC.encode(cells) == Frame(503, data)
    # Bits 4..7 of byte 6 and bytes 4..5 carry no cell: documented as ignored, not malformed.
    noisy = bytes([0x4A, 0xF4, 0x00, 0x01, 0x12, 0x34, 0b1111_1110])
    assert CODEC.decode(503, noisy) == cells


def test_config_golden_frames_both_ways():
    frames = CODEC.config_frames(Bms16Settings(**GOOD_CONFIG))
    assert frames == [Frame(504, GOOD_504), Frame(505, GOOD_505)]
    assert CODEC.decode(504, GOOD_504) == Bms16ConfigPart1(16, 100.0, 20.0, 58.0, 200.0,
                                                           300.0, 60.0, 2.8)
    assert CODEC.decode(505, GOOD_505) == Bms16ConfigPart2(3.65, 0.1, 3.45, 200)


def test_config_accepts_natural_spellings():
    spelled = dict(GOOD_CONFIG, cells=16.0, pack_capacity_ah=100.0, min_cell_v=2.80,
                   shunt_size_a=200.0, hysteresis_v=0)
    assert CODEC.config_frames(Bms16Settings(**spelled))[1].data == bytes([73, 0, 69, 2])


@pytest.mark.parametrize('size, code', [(0, 0), (100, 1), (200, 2), (500, 3)])
def test_every_shunt_size(size, code):
    frame = CODEC.config_frames(Bms16Settings(**dict(GOOD_CONFIG, shunt_size_a=size)))[1]
    assert frame.data[3] == code
    assert CODEC.decode(505, frame.data).shunt_size_a == size


@pytest.mark.parametrize('field, low, high, step', [
    (f.name, f.low, f.high, f.step) for f in CONFIG_FIELDS if f.name != 'shunt_size_a'])
def test_config_range_edges_and_refusals(field, low, high, step):
    for ok in (low, high):
        check_config_value(field, ok)
        CODEC.config_frames(Bms16Settings(**dict(GOOD_CONFIG, **{field: ok})))
    for bad in (low - step, high + step, low + step / 2, float('nan'), True, '3'):
        with pytest.raises(EncodeRangeError) as info:
            CODEC.config_frames(Bms16Settings(**dict(GOOD_CONFIG, **{field: bad})))
        assert info.value.field == field
        assert f'{low:g}..{high:g}' in str(info.value)


@pytest.mark.parametrize('bad', [50, 300, -100, 1000, 200.5, None])
def test_shunt_size_refusals_name_the_choices(bad):
    with pytest.raises(EncodeRangeError) as info:
        CODEC.config_frames(Bms16Settings(**dict(GOOD_CONFIG, shunt_size_a=bad)))
    assert info.value.field == 'shunt_size_a'
    assert '0 (no shunt), 100, 200 or 500 A' in str(info.value)


def test_config_fields_describe_every_config_value():
    assert [f.name for f in CONFIG_FIELDS] == list(GOOD_CONFIG)
    assert all(f.description and f.low is not None and f.high is not None
               for f in CONFIG_FIELDS)


def test_config_parts_encode_like_config_frames():
    assert CODEC.encode(CODEC.decode(504, GOOD_504)) == Frame(504, GOOD_504)
    assert CODEC.encode(CODEC.decode(505, GOOD_505)) == Frame(505, GOOD_505)


@pytest.mark.parametrize('frame_id, message', [
    (506, AcknowledgeError()), (507, ResetSoc()), (508, PowerOff())])
def test_commands_have_no_data(frame_id, message):
    assert CODEC.encode(message) == Frame(frame_id, b'')
    assert CODEC.decode(frame_id, b'') == message


def test_base_id_moves_every_id():
    codec = Bms16Codec(0x100)
    assert codec.arbitration_ids == frozenset(range(0x100, 0x109))
    assert codec.decode(0x101, bytes(7)).first_cell == 0
    assert codec.encode(PowerOff()) == Frame(0x108, b'')
    with pytest.raises(EncodeRangeError):
        Bms16Codec(0x7FA)


@pytest.mark.parametrize('frame_id, dlc', [
    (500, 7), (501, 7), (502, 7), (503, 7), (504, 8), (505, 4), (506, 0), (507, 0), (508, 0)])
def test_wrong_dlc_is_malformed(frame_id, dlc):
    for wrong in (dlc - 1, dlc + 1):
        if 0 <= wrong <= 8:
            with pytest.raises(MalformedFrameError, match=f'DLC {wrong}, expected {dlc}'):
                CODEC.decode(frame_id, bytes(wrong))


@pytest.mark.parametrize('code', [9, 100, 255])
def test_unknown_error_code_is_malformed(code):
    with pytest.raises(MalformedFrameError, match=f'error code {code}'):
        CODEC.decode(500, bytes([code, 0, 0, 0, 0, 0x80, 0]))


def test_unknown_shunt_code_and_foreign_id_are_malformed():
    with pytest.raises(MalformedFrameError, match='shunt size code 4'):
        CODEC.decode(505, bytes([73, 2, 69, 4]))
    with pytest.raises(MalformedFrameError):
        CODEC.decode(509, b'')


def test_telemetry_encoders_refuse_what_the_wire_cannot_carry():
    with pytest.raises(EncodeRangeError, match='current_a'):
        CODEC.encode(Bms16Status(Bms16Error.NONE, 50, 50.0, 3300.0, 20))
    with pytest.raises(EncodeRangeError, match='cell2_v'):
        CODEC.encode(Bms16Cells(0, (3.3, 5.2, 3.3, 3.3, 3.3, 3.3)))
    with pytest.raises(EncodeRangeError, match='exactly 4'):
        CODEC.encode(Bms16Cells(12, (3.3,) * 6))
    with pytest.raises(EncodeRangeError, match='error'):
        CODEC.encode(Bms16Status(9, 50, 50.0, 0.0, 20))


@settings(max_examples=200, deadline=None)
@given(st.integers(500, 508), st.binary(max_size=8))
def test_any_frame_decodes_or_is_malformed(frame_id, data):
    assert_decodes_or_malformed(CODEC, frame_id, data)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 8), st.integers(0, 100), st.integers(0, 800),  # the document's ranges
       st.integers(22768, 42768), st.integers(0, 120))
def test_status_round_trip(error, soc, volts, amps, temp):
    data = bytes([error, soc, volts & 0xFF, volts >> 8, amps & 0xFF, amps >> 8, temp])
    assert CODEC.encode(CODEC.decode(500, data)).data == data


@settings(max_examples=200, deadline=None)
@given(st.integers(501, 503), st.lists(st.integers(0, 500), min_size=6, max_size=6))
def test_cells_round_trip(frame_id, raws):
    count = 4 if frame_id == 503 else 6
    data = bytearray(7)
    for k, raw in enumerate(raws[:count]):
        data[k] = raw & 0xFF
        data[6] |= (raw >> 8) << k
    cells = CODEC.decode(frame_id, bytes(data))
    assert [round(v * 100) for v in cells.voltages_v] == raws[:count]
    assert CODEC.encode(cells).data == bytes(data)


@settings(max_examples=200, deadline=None)
@given(st.tuples(
    st.integers(12, 16), st.integers(1, 100), st.integers(0, 100), st.integers(0, 100),
    st.integers(0, 100), st.integers(0, 100), st.integers(0, 100), st.integers(20, 100),
    st.integers(20, 100), st.integers(0, 20), st.integers(20, 100), st.integers(0, 3)))
def test_config_round_trip(raw):
    frames = [Frame(504, bytes(raw[:8])), Frame(505, bytes(raw[8:]))]
    part1 = CODEC.decode(504, frames[0].data)
    part2 = CODEC.decode(505, frames[1].data)
    config = Bms16Settings(**vars(part1), **vars(part2))
    assert CODEC.config_frames(config) == frames


@pytest.mark.parametrize('offset,data,reason', [
    (0, bytes([0, 101, 0, 0, 0, 0x80, 20]), 'SoC 101 %'),
    (0, bytes([0, 186, 0, 0, 0, 0x80, 20]), 'SoC 186 %'),
    (4, bytes([17, 10, 20, 58, 10, 20, 60, 60]), 'cells 17, allowed 12..16'),
    (4, bytes([16, 0, 20, 58, 10, 20, 60, 60]), 'pack_capacity_ah 0, allowed 10..1000'),
    (4, bytes([16, 10, 20, 58, 10, 20, 60, 10]), 'min_cell_v 0.5, allowed 1..5'),
    (4, bytes([16, 10, 101, 58, 10, 20, 60, 60]), 'soc_warning_pct 101, allowed 0..100'),
    (5, bytes([84, 25, 80, 1]), 'hysteresis_v 1.25, allowed 0..1'),
    (5, bytes([101, 2, 80, 1]), 'max_cell_v 5.05, allowed 1..5'),
])
def test_values_outside_the_documented_ranges_are_malformed(offset, data, reason):
    with pytest.raises(MalformedFrameError, match=reason):
        CODEC.decode(CODEC.base_id + offset, data)


def test_documented_range_edges_decode():
    assert CODEC.decode(CODEC.base_id, bytes([0, 100, 0, 0, 0, 0x80, 20])).soc_pct == 100
    part1 = CODEC.decode(CODEC.base_id + 4, bytes([12, 100, 100, 100, 100, 100, 100, 20]))
    assert (part1.cells, part1.pack_capacity_ah, part1.min_cell_v) == (12, 1000.0, 1.0)
    part2 = CODEC.decode(CODEC.base_id + 5, bytes([100, 20, 20, 3]))
    assert (part2.max_cell_v, part2.hysteresis_v, part2.balance_v) == (5.0, 1.0, 1.0)
