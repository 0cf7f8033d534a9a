# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
EVMS3 configuration read-back (ID 51 -> 52..56), golden frames written by hand.

Facts (issue 10, ZEVA's open EVMS3 firmware, MIT, August 2021): ID 51 with any data (DLC 0
is enough) asks; 52..55 answer in exactly the layout of 32..35 and 56 in the layout of 36.
"""
import cantools
import pytest

from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.common import Frame, msg_defs_dir
from ams_can_bridge.protocols.evms3 import (
    ConfigReadback, ConfigReport, Evms3Codec, OtherTraffic, RequestConfig)
from shared import (EVMS3_ANSWER as ANSWER, EVMS3_ANSWER_CELLS as CELLS,
                    EVMS3_GOLDEN_CONFIG as CONFIG)  # written and read back

CODEC = Evms3Codec(bms12_modules=2)


def test_request_is_id_51_without_data():
    assert CODEC.encode(RequestConfig()) == Frame(51, b'', True)
    assert Evms3Codec(extended_id=False).encode(RequestConfig()) == Frame(51, b'', False)


def test_answer_golden_joins_into_one_configuration():
    reports = [CODEC.decode(i, data) for i, data in ANSWER.items()]
    assert [r.arbitration_id for r in reports] == [52, 53, 54, 55, 56]
    assert reports[4] == ConfigReport(56, {'cells_per_module': CELLS})
    readback = ConfigReadback.join(reversed(reports))  # any order
    assert readback == ConfigReadback(CONFIG, CELLS, ())
    assert readback.summary() == (
        '100 Ah, full 400 V, cells 2.80..3.65 V, balance static 3.50 V, charge 300 V 30 A, '
        '5 BMS12 module(s) with 41 cells')
    values = readback.parameter_values()
    assert values['balance_v'] == 3.5 and values['balance_mode'] == 'static'
    assert values['cells_per_module'] == list(CELLS) and len(values) == 34
    assert values['reverse_current_display'] is True and values['night_brightness'] == 7
    assert CODEC.report_frames(CONFIG, CELLS) == [
        Frame(i, data, True) for i, data in ANSWER.items()]


@pytest.mark.parametrize('raw, mode', [(251, 'dynamic'), (252, 'off')])
def test_balance_mode_from_251_252_has_no_voltage(raw, mode):
    data = bytearray(ANSWER[53])
    data[7] = raw
    answer = {**ANSWER, 53: bytes(data)}
    readback = ConfigReadback.join(CODEC.decode(i, d) for i, d in answer.items())
    assert readback.config.balance_mode == mode and readback.config.balance_v is None
    assert 'balance_v' not in readback.parameter_values()
    assert f'balance {mode}' in readback.summary()


def test_partial_answer_names_what_is_missing():
    readback = ConfigReadback.join([CODEC.decode(52, ANSWER[52]), CODEC.decode(55, ANSWER[55])])
    assert readback.config is None and readback.missing == (53, 54, 56)
    assert readback.summary() == ('incomplete: missing ID 53 (config 2), ID 54 (config 3), '
                                  'ID 56 (cell numbers)')
    assert readback.parameter_values() == {}


def test_answer_values_out_of_range_are_malformed():
    with pytest.raises(MalformedFrameError, match='sleep_delay_min raw 0'):
        CODEC.decode(54, ANSWER[54][:7] + b'\x00')
    with pytest.raises(MalformedFrameError, match='DLC 7'):
        CODEC.decode(54, ANSWER[54][:7])
    with pytest.raises(MalformedFrameError, match='DLC 6'):
        CODEC.decode(55, ANSWER[55][:6])  # bytes 6-7 are settings 30-31


def test_52_and_53_that_are_no_evms3_packet_are_other_traffic():
    # Common.h: 52/53 are also MC_RECEIVE_SETTINGS_ID / MC_SEND_SETTINGS_ID
    assert isinstance(CODEC.decode(53, bytes([7]) + ANSWER[53][1:]), OtherTraffic)
    assert isinstance(CODEC.decode(52, ANSWER[52][:7]), OtherTraffic)
    assert isinstance(CODEC.decode(52, b'\x00'), OtherTraffic)


def test_ids_51_to_56_are_fixed_and_51_is_not_listened_to():
    moved = Evms3Codec(base_id=1000)
    assert {(i, True) for i in range(52, 57)} <= moved.frame_ids
    assert 51 not in moved.arbitration_ids  # may be a ZEVA motor controller's throttle
    assert moved.encode(RequestConfig()).arbitration_id == 51
    narrow = Evms3Codec(extended_id=False)
    assert (52, False) in narrow.frame_ids and (52, True) not in narrow.frame_ids
    with pytest.raises(ValueError, match='51..56'):
        Evms3Codec(base_id=45)


def test_dbc_has_the_read_back_messages():
    db = cantools.database.load_file(str(msg_defs_dir() / 'evms3.dbc'), strict=True)
    request = db.get_message_by_frame_id(51, force_extended_id=True)
    assert (request.name, request.length) == ('EVMS3_RequestConfig', 0)
    answer = db.get_message_by_frame_id(53, force_extended_id=True)
    decoded = answer.decode(ANSWER[53], decode_choices=False)
    assert decoded['BmsMinVoltage'] == pytest.approx(2.8)
    assert decoded['BalanceVoltage'] == pytest.approx(3.5)
    cells = db.get_message_by_frame_id(56, force_extended_id=True).decode(ANSWER[56])
    assert (cells['Module0Cells'], cells['Module1Cells'], cells['Module15Cells']) == (12, 8, 12)
