# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""IVT-S codec: golden frames written by hand from doc/protocols.md s. 2, not from the DBC."""
import math

from hypothesis import given, settings, strategies as st
import pytest

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import Frame, load_dbc
from ams_can_bridge.protocols.ivt_s import IvtMux, IvtResult, IvtSCodec, LAYOUTS, RAW_LIMITS

BE = IvtSCodec()
LE = IvtSCodec(byte_order='little')

# (ID, big-endian frame, little-endian frame, kind, counter, raw, SI value), by hand:
# b0 MuxID, b1 counter (no status bits), b2..b5 the signed 32-bit value.
GOLDEN = [
    (0x521, '00 00 00 00 05 DC', '00 00 DC 05 00 00', IvtMux.I, 0, 1500, 1.5),  # 1.5 A
    (0x521, '00 0F FF FF FA 24', '00 0F 24 FA FF FF', IvtMux.I, 15, -1500, -1.5),
    (0x522, '01 03 00 06 1A 80', '01 03 80 1A 06 00', IvtMux.U1, 3, 400000, 400.0),
    (0x523, '02 07 00 00 00 01', '02 07 01 00 00 00', IvtMux.U2, 7, 1, 0.001),
    (0x524, '03 0A FF FF FF FF', '03 0A FF FF FF FF', IvtMux.U3, 10, -1, -0.001),
    (0x525, '04 01 00 00 00 FB', '04 01 FB 00 00 00', IvtMux.T, 1, 251, 25.1),  # 25.1 degC
    (0x525, '04 02 FF FF FF 9C', '04 02 9C FF FF FF', IvtMux.T, 2, -100, -10.0),
    (0x526, '05 04 00 00 9C 40', '05 04 40 9C 00 00', IvtMux.W, 4, 40000, 40000.0),
    (0x527, '06 05 FF FE 79 60', '06 05 60 79 FE FF', IvtMux.AS, 5, -100000, -100000.0),
    (0x528, '07 0E 00 00 04 D2', '07 0E D2 04 00 00', IvtMux.WH, 14, 1234, 1234.0),
    (0x521, '00 08 7F FF FF FF', '00 08 FF FF FF 7F', IvtMux.I, 8, 2147483647, 2147483.647),
    (0x521, '00 09 80 00 00 00', '00 09 00 00 00 80', IvtMux.I, 9, -2147483648, -2147483.648),
]


@pytest.mark.parametrize('codec_name', ['big', 'little'])
@pytest.mark.parametrize('case', GOLDEN, ids=lambda c: f'{c[3].name}={c[5]}')
def test_golden_frames_decode_and_encode(codec_name, case):
    can_id, be_hex, le_hex, kind, counter, raw, value = case
    codec = BE if codec_name == 'big' else LE
    data = bytes.fromhex(be_hex if codec_name == 'big' else le_hex)
    result = codec.decode(can_id, data)
    assert result.kind is kind
    assert result.counter == counter
    assert result.raw == raw
    assert result.value == pytest.approx(value, rel=1e-12)
    assert not (result.ocs or result.result_error or result.measurement_error
                or result.system_error)
    assert codec.encode(result) == Frame(can_id, data, False)


@pytest.mark.parametrize('bit, field', [
    (0x10, 'ocs'), (0x20, 'result_error'), (0x40, 'measurement_error'),
    (0x80, 'system_error')])
def test_each_status_bit_alone(bit, field):
    result = BE.decode(0x526, bytes([5, bit | 0x06, 0, 0, 0, 7]))
    flags = {f: getattr(result, f) for f in
             ('ocs', 'result_error', 'measurement_error', 'system_error')}
    assert flags == {f: f == field for f in flags}
    assert result.counter == 6 and result.raw == 7  # status bits do not leak into them
    assert result.status_bits == bit


def test_all_status_bits_with_counter_15():
    result = LE.decode(0x528, bytes.fromhex('07 FF 00 00 00 00'))
    assert (result.counter, result.ocs, result.result_error, result.measurement_error,
            result.system_error) == (15, True, True, True, True)


def test_ids_follow_base_id_and_are_standard():
    codec = IvtSCodec(base_id=0x600)
    assert codec.arbitration_ids == frozenset(range(0x600, 0x608))
    assert codec.is_extended_id is False
    assert codec.decode(0x605, bytes([5, 0, 0, 0, 0, 2])).kind is IvtMux.W
    assert BE.arbitration_ids == frozenset(range(0x521, 0x529))
    assert 0x411 not in BE.arbitration_ids and 0x511 not in BE.arbitration_ids


@pytest.mark.parametrize('can_id, data, reason', [
    (0x521, '00 00 00 00 00', 'DLC 5, expected 6'),
    (0x521, '00 00 00 00 00 00 00', 'DLC 7, expected 6'),
    (0x522, '', 'DLC 0, expected 6'),
    (0x522, '00 00 00 00 00 01', 'MuxID 0 does not match result U1'),
    (0x528, '08 00 00 00 00 01', 'MuxID 8 does not match result WH'),
    (0x521, 'FF 00 00 00 00 01', 'MuxID 255'),
    (0x511, '00 00 00 00 00 00', 'not an IVT-S result ID'),
])
def test_malformed_frames_are_rejected_with_reason(can_id, data, reason):
    with pytest.raises(MalformedFrameError, match=reason) as info:
        BE.decode(can_id, bytes.fromhex(data))
    assert info.value.arbitration_id == can_id


@pytest.mark.parametrize('order', ['BIG', 'le', '', 'network'])
def test_bad_byte_order_names_allowed_values(order):
    with pytest.raises(ValueError, match="'big' | 'little'"):
        IvtSCodec(byte_order=order)


def test_bad_base_id_is_refused():
    with pytest.raises(ValueError, match='base_id'):
        IvtSCodec(base_id=0x7FC)


def test_encode_refuses_out_of_range():
    with pytest.raises(EncodeRangeError, match='counter'):
        BE.encode(IvtResult(IvtMux.I, 16, False, False, False, False, 0, 0.0))
    with pytest.raises(EncodeRangeError, match='raw value'):
        BE.encode(IvtResult(IvtMux.U1, 0, False, False, False, False, 1 << 31, 0.0))
    with pytest.raises(EncodeRangeError, match='finite'):
        IvtResult.from_value(IvtMux.I, math.nan)


def test_from_value_rounds_to_vendor_unit():
    result = IvtResult.from_value(IvtMux.T, 23.46, counter=3, ocs=True)
    assert (result.raw, result.value, result.counter, result.ocs) == (235, 23.5, 3, True)
    assert IvtResult.from_value(IvtMux.I, -12.3456).raw == -12346


@settings(max_examples=200, deadline=None)
@given(offset=st.integers(0, 7), data=st.binary(min_size=0, max_size=8),
       order=st.sampled_from(['big', 'little']))
def test_random_data_decodes_or_raises_malformed(offset, data, order):
    codec = BE if order == 'big' else LE
    try:
        result = codec.decode(0x521 + offset, data)
    except MalformedFrameError:
        assert len(data) != 6 or data[0] != offset
        return
    assert len(data) == 6 and data[0] == offset
    assert result.kind == offset and 0 <= result.counter <= 15
    assert codec.encode(result).data == data


@settings(max_examples=200, deadline=None)
@given(kind=st.sampled_from(list(IvtMux)), raw=st.integers(-(1 << 31), (1 << 31) - 1),
       counter=st.integers(0, 15), bits=st.integers(0, 15),
       order=st.sampled_from(['big', 'little']))
def test_encode_decode_round_trip(kind, raw, counter, bits, order):
    codec = BE if order == 'big' else LE
    low, high = RAW_LIMITS[kind]  # T: -273.1..200 degC (doc/protocols.md 2.1)
    raw = low + (raw - low) % (high - low + 1)
    result = IvtResult(kind, counter, bool(bits & 1), bool(bits & 2), bool(bits & 4),
                       bool(bits & 8), raw, raw / (1000 if kind <= IvtMux.U3 else
                                                   10 if kind == IvtMux.T else 1))
    frame = codec.encode(result)
    assert frame.arbitration_id == 0x521 + kind and len(frame.data) == 6
    assert codec.decode(frame.arbitration_id, frame.data) == result


@settings(max_examples=100, deadline=None)
@given(offset=st.integers(0, 7), tail=st.binary(min_size=5, max_size=5))
def test_big_endian_codec_agrees_with_the_dbc(offset, tail):
    # The DBC describes the factory (big-endian) layout: both readers must agree.
    data = bytes([offset]) + tail
    theirs = load_dbc('ivt_s').decode_message(0x521 + offset, data, decode_choices=False)
    name = ['I', 'U1', 'U2', 'U3', 'T', 'W', 'As', 'Wh'][offset]
    low, high = RAW_LIMITS[IvtMux(offset)]
    if not low <= int.from_bytes(tail[1:], 'big', signed=True) <= high:
        with pytest.raises(MalformedFrameError):  # outside the DBC's range: no temperature
            BE.decode(0x521 + offset, data)
        return
    ours = BE.decode(0x521 + offset, data)
    assert theirs[f'IVT_MsgCount_Result_{name}'] == ours.counter
    assert theirs[f'IVT_Result_{name}_OCS'] == ours.ocs
    assert theirs[f'IVT_Result_{name}_Channel_Error'] == ours.result_error
    assert theirs[f'IVT_Result_{name}_Measurement_Error'] == ours.measurement_error
    assert theirs[f'IVT_Result_{name}_System_Error'] == ours.system_error
    # The DBC keeps vendor units (T in 0.1 degC steps); ours.value is SI.
    dbc_value = theirs[f'IVT_Result_{name}']
    expected = ours.value * (1000 if offset <= 3 else 1)
    assert dbc_value == pytest.approx(expected, rel=1e-9, abs=1e-6)


def test_the_result_state_bits_are_named_as_the_vendor_dbc_names_them():
    """
    Name and place the status bits as Isabellenhuette's DBC does.

    IVT-S_12082020.dbc (foxBMS 2 tools/dbc/third-party), message 1313:
    IVT_Result_I_System_Error 15|1, IVT_Result_I_Measurement_Error 14|1,
    IVT_Result_I_Channel_Error 13|1, IVT_Result_I_OCS 12|1, IVT_MsgCount_Result_I 11|4.
    """
    message = load_dbc('ivt_s').get_message_by_frame_id(0x521)
    bits = {s.name: (s.start, s.length) for s in message.signals}
    assert {name: bits[name] for name in (
        'IVT_Result_I_System_Error', 'IVT_Result_I_Measurement_Error',
        'IVT_Result_I_Channel_Error', 'IVT_Result_I_OCS', 'IVT_MsgCount_Result_I')} == {
        'IVT_Result_I_System_Error': (15, 1), 'IVT_Result_I_Measurement_Error': (14, 1),
        'IVT_Result_I_Channel_Error': (13, 1), 'IVT_Result_I_OCS': (12, 1),
        'IVT_MsgCount_Result_I': (11, 4)}
    assert [s.name for s in LAYOUTS[IvtMux.WH].signals][3] == 'IVT_Result_Wh_Channel_Error'
