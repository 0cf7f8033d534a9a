# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Bad .asc lines are counted (issue 34, 9): python-can's ASCReader drops them without a word.

A NaN, inf or 1e308 timestamp does not match its frame pattern and the line is skipped; a
classic frame with DLC 15 and 2 data bytes is read as a frame of 64 bytes holding 2. log2bag
counts each as a bad log entry and says what the last one was.
"""
import can
import pytest

from ams_can_bridge.errors import LogFileError
from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.offline.log_frames import LogFrames

HEAD = ('date Sat Nov 28 10:00:00.000 am 2026\nbase hex  timestamps absolute\n'
        'internal events logged\nBegin TriggerBlock Sat Nov 28 10:00:00.000 am 2026\n'
        '   0.000000 Start of measurement\n')
GOOD = '   {t} 1  521             Rx   d 6 00 00 00 00 00 00\n'
OTHER = ('   0.015000 1  Statistic: D 0 R 0 XD 0 XR 0 E 0 O 0 B 0.00%\n'
         '// a comment\n   0.016000 CAN 1 Status:chip status error active\n')
BAD = ['   nan 1  521             Rx   d 6 00 00 00 00 00 00\n',
       '   inf 1  521             Rx   d 6 00 00 00 00 00 00\n',
       '   1e308 1  521             Rx   d 6 00 00 00 00 00 00\n',
       '   0.020000 1  521             Rx   d f 01 02\n']


def write(path, lines) -> str:
    path.write_text(HEAD + ''.join(lines) + 'End TriggerBlock\n', encoding='utf-8')
    return str(path)


def test_bad_entries_are_counted_in_the_summary(tmp_path):
    goods = [GOOD.format(t=f'0.0{k}0000') for k in range(3, 8)]
    log = write(tmp_path / 'bad.asc', [GOOD.format(t='0.010000'), OTHER] + BAD + goods)
    summary = convert(log, str(tmp_path / 'bag'), {'devices': ['ivt_s']})
    assert summary.frames_read == 6
    assert summary.bad_entries == 4
    assert 'data length 64 (its DLC) with 2 data bytes' in summary.last_bad
    assert 'bad log entries skipped: 4' in summary.text()


def test_four_bad_entries_in_one_read_is_no_log_to_convert(tmp_path):
    # the file: it said "bad log entries skipped: 0"
    log = write(tmp_path / 'bad.asc', [GOOD.format(t='0.010000'), OTHER] + BAD)
    with pytest.raises(LogFileError, match=r'most entries are unreadable \(4 of 5\)'):
        convert(log, str(tmp_path / 'bag'), {'devices': ['ivt_s']})


def test_each_bad_line_is_named_where_it_is(tmp_path):
    for k, bad in enumerate(BAD[:3]):
        log = write(tmp_path / f'one{k}.asc', [GOOD.format(t='0.010000'), bad,
                                               GOOD.format(t='0.030000')])
        frames = LogFrames(log)
        assert len(list(frames)) == 2
        frames.close()
        assert frames.bad == 1 and 'line 7:' in frames.last_bad, frames.last_bad


def test_a_good_asc_has_no_bad_entry(tmp_path):
    log = str(tmp_path / 'good.asc')
    with can.Logger(log) as writer:
        for k in range(50):
            writer.on_message_received(can.Message(
                timestamp=1_790_000_000 + k * 0.01, arbitration_id=0x521, data=bytes(k % 9),
                is_extended_id=bool(k % 2), is_remote_frame=k % 7 == 0))
    frames = LogFrames(log)
    assert len(list(frames)) == 50
    frames.close()
    assert frames.bad == 0, frames.last_bad
