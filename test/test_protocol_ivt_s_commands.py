# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
IVT-S commands (0x411) and answers (0x511) against golden frames written by hand.

The bytes come from the public sources (doc/protocols.md section 2): the vendor DBC
IVT-S_12082020.dbc, the EVtv/Stm32-vcu isa_shunt.cpp and sectioncritical/ivts.
"""
import pytest

from ams_can_bridge.protocols import ivt_s_commands as cmd
from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.ivt_s import IvtMux
from ams_can_bridge.protocols.ivt_s_commands import (
    AliveAnswer, ErrorAnswer, ModeAnswer, OtherAnswer, ResetAnswer, ResultConfig, SerialAnswer,
    StoreAnswer, TriggerMode, WrongCommand)


def frame(*data):
    return Frame(0x411, bytes(data), False)


# --- commands: the bytes the sources send ---------------------------------------------------
def test_stm32_vcu_stop_start_store_restart_defaults():
    # isa_shunt.cpp STOP / START / sendSTORE / RESTART / deFAULT, byte for byte
    assert cmd.set_mode(False) == frame(0x34, 0x00, 0x01, 0, 0, 0, 0, 0)
    assert cmd.set_mode(True) == frame(0x34, 0x01, 0x01, 0, 0, 0, 0, 0)
    assert cmd.store() == frame(0x32, 0, 0, 0, 0, 0, 0, 0)
    assert cmd.restart() == frame(0x3F, 0, 0, 0, 0, 0, 0, 0)
    assert cmd.RESTART_DEFAULT == 0x3D


def test_stm32_vcu_initialize_config_frames():
    # isa_shunt.cpp initialize(): 0x20+i, 0x42 (cyclic, little-endian), 0x00 0x64 (100 ms)
    for kind in IvtMux:
        config = ResultConfig(kind, TriggerMode.CYCLIC, 100, little_endian=True)
        assert cmd.set_config(config) == frame(0x20 + kind, 0x42, 0x00, 0x64, 0, 0, 0, 0)


def test_ivts_encoder_config_frames():
    # ivts.Encoder.set_config(T, CYCLIC, 311) and (U2, DISABLED, 60) from config_and_store.py
    assert cmd.set_config(ResultConfig(IvtMux.T, TriggerMode.CYCLIC, 311)) == frame(
        0x24, 0x02, 0x01, 0x37, 0, 0, 0, 0)
    assert cmd.set_config(ResultConfig(IvtMux.U2, TriggerMode.DISABLED, 60)) == frame(
        0x22, 0x00, 0x00, 0x3C, 0, 0, 0, 0)
    # ivts.Encoder.set_run_mode(False) / (True): startup RUN by default
    assert cmd.set_mode(False) == frame(0x34, 0, 1, 0, 0, 0, 0, 0)


def test_sign_bit_and_big_endian_from_the_dbc_layout():
    # DBC _20_Conf_Sign_I 15|1 = byte 1 bit 7, _20_Conf_Endianess_I 14|1 = byte 1 bit 6,
    # _20_Conf_CycleTime_I 23|16 (Motorola) = bytes 2..3 big-endian
    config = ResultConfig(IvtMux.I, TriggerMode.CYCLIC, 0x1234, sign_inverted=True)
    assert cmd.set_config(config) == frame(0x20, 0x82, 0x12, 0x34, 0, 0, 0, 0)
    triggered = ResultConfig(IvtMux.WH, TriggerMode.TRIGGERED, 1, True, True)
    assert cmd.set_config(triggered) == frame(0x27, 0xC1, 0x00, 0x01, 0, 0, 0, 0)


def test_error_masks_bit_5_from_the_datasheet():
    # IVT-S datasheet, set config result, byte 1: bits 1..0 mode, bit 4 reserved, bit 5 = 1:
    # the error masks set the result state bits, bit 6 endianness, bit 7 sign
    config = ResultConfig(IvtMux.I, TriggerMode.CYCLIC, 20, error_masks=True)
    assert cmd.set_config(config) == frame(0x20, 0x22, 0x00, 0x14, 0, 0, 0, 0)
    every = ResultConfig(IvtMux.WH, TriggerMode.CYCLIC, 30, True, True, True)
    assert cmd.set_config(every) == frame(0x27, 0xE2, 0x00, 0x1E, 0, 0, 0, 0)
    answer = bytes([0xA4, 0x20, 0x00, 0x64, 0, 0, 0, 0])  # T disabled 100 ms, masks on
    assert cmd.decode_answer(answer) == ResultConfig(IvtMux.T, TriggerMode.DISABLED, 100,
                                                     error_masks=True)
    assert cmd.decode_answer(answer).text() == ('disabled, big-endian, sign normal, error '
                                                'masks in the result state')


def test_getters_and_reset_frames():
    assert cmd.get_config(IvtMux.I) == frame(0x60, 0, 0, 0, 0, 0, 0, 0)
    assert cmd.get_config(IvtMux.WH) == frame(0x67, 0, 0, 0, 0, 0, 0, 0)
    assert cmd.get_mode() == frame(0x74, 0, 0, 0, 0, 0, 0, 0)
    assert cmd.get_serial() == frame(0x7B, 0, 0, 0, 0, 0, 0, 0)
    # DBC _30_Reset_Item 15|16, _30_Reset_Device_SN 31|32; items 0 / 256 (value table)
    assert cmd.reset_errors(0, 0x01020304) == frame(0x30, 0x00, 0x00, 1, 2, 3, 4, 0)
    assert cmd.reset_errors(256, 0xA0B0C0D0) == frame(0x30, 0x01, 0x00, 0xA0, 0xB0, 0xC0,
                                                      0xD0, 0)


def test_out_of_range_values_are_refused():
    with pytest.raises(EncodeRangeError, match='0..65535'):
        cmd.set_config(ResultConfig(IvtMux.I, TriggerMode.CYCLIC, 65536))
    with pytest.raises(EncodeRangeError):
        cmd.reset_errors(0, 1 << 32)


# --- answers ---------------------------------------------------------------------------------
@pytest.mark.parametrize('data, answer', [
    ([0xA0, 0x42, 0x00, 0x64, 0, 0, 0, 0],
     ResultConfig(IvtMux.I, TriggerMode.CYCLIC, 100, True, False)),
    ([0xA5, 0x82, 0x00, 0x0A, 0, 0, 0, 0],
     ResultConfig(IvtMux.W, TriggerMode.CYCLIC, 10, False, True)),
    ([0xA3, 0x00, 0x00, 0x3C, 0, 0, 0, 0],
     ResultConfig(IvtMux.U3, TriggerMode.DISABLED, 60, False, False)),
    ([0xB4, 0x01, 0x01, 0, 0, 0, 0, 0], ModeAnswer(True, True)),  # _B4_Resp_Actual_Mode 8|1
    ([0xB4, 0x00, 0x01, 0, 0, 0, 0, 0], ModeAnswer(False, True)),
    ([0xB2, 0, 0, 0, 0, 0, 0, 0], StoreAnswer()),
    ([0xBF, 0x04, 0x11, 0x00, 0x01, 0x23, 0x45, 0], AliveAnswer(0x411, 0x12345)),
    ([0xBB, 0x00, 0x01, 0x23, 0x45, 0, 0, 0], SerialAnswer(0x12345)),  # 15|32
    ([0xB0, 0x01, 0x00, 0, 1, 0x23, 0x45, 0], ResetAnswer(256, 0x12345)),
    ([0x81, 0x05, 0x00, 0x03, 0, 0, 0, 0], ErrorAnswer(True, 5, 3)),
    ([0x80, 0x00, 0x12, 0x34, 0, 0, 0, 0], ErrorAnswer(False, 0, 0x1234)),
    ([0xFF, 0x99, 0, 0, 0, 0, 0, 0], WrongCommand(0x99)),
    ([0x90, 1, 2, 3, 4, 5, 6, 7], OtherAnswer(0x90, bytes([0x90, 1, 2, 3, 4, 5, 6, 7]))),
])
def test_answers_decode_and_encode_back(data, answer):
    assert cmd.decode_answer(bytes(data)) == answer
    assert cmd.encode_answer(answer) == Frame(0x511, bytes(data), False)


def test_error_answer_names_the_vendor_item():
    assert ErrorAnswer(True, 5, 3).text() == 'system error item 5 (overtemperature): 0x0003'
    assert 'Vref' in ErrorAnswer(False, 6, 1).text()


@pytest.mark.parametrize('data, reason', [
    (bytes([0xB4, 1, 1]), 'DLC 3'),
    (b'', 'DLC 0'),
    (bytes([0xA0, 0x03, 0, 10, 0, 0, 0, 0]), 'trigger mode 3'),
])
def test_malformed_answers(data, reason):
    with pytest.raises(MalformedFrameError, match=reason):
        cmd.decode_answer(data)


def test_config_text():
    config = ResultConfig(IvtMux.I, TriggerMode.CYCLIC, 10, True, True)
    assert config.text() == 'cyclic 10 ms, little-endian, sign inverted'
    assert ResultConfig(IvtMux.T, TriggerMode.DISABLED, 60).text() == \
        'disabled, big-endian, sign normal'
