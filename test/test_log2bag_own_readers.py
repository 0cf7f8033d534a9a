# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's own readers give python-can's frames and counts, line by line and object by object.

``LogFrames.frames()`` reads a candump ``.log`` with ``offline/candump_frames.py`` and a
``.blf`` with ``offline/blf_frames.py`` instead of python-can's readers (issue 39: no
``can.Message`` per frame). Each test reads a file both ways and asserts the same tuples
(compared by ``repr``: the same types too, a bool is not an int) and the same counters
(``bad``, ``last_bad``, ``bad_stamps``, ``stopped``, ``truncated``, ``cut_line``): the
reference is ``LogFrames`` iterated (python-can's reader and LogFrames' checks, as before
the own readers) and, for files python-can reads whole, a bare ``can.LogReader``. This
file: every candump .log of the fixtures and crafted lines; the BLF cases are
``test_log2bag_own_readers_blf.py``'s.
"""
from __future__ import annotations

from pathlib import Path
import random

import pytest

from ams_can_bridge.offline import candump_frames
from ams_can_bridge.offline.log_frames import LogFrames
from shared import bare_python_can, frame_counts as counts, read_both_ways as read_both

FIXTURES = Path(__file__).parent / 'fixtures'
FIXTURE_LOGS = sorted(FIXTURES.rglob('*.log'))
# Common lines, as candump -L writes them and as python-can's writer does (with a direction)
CANDUMP = [
    '(1790000000.000000) can0 311#0102030405060708',
    '(1790000000.001000) vcan0 18FF50E5#01',
    '(1790000000.002500) can0 300#',
    '(1790000000.004000) can1 1FFFFFFF#aabbccddeeff0011',
    '(1790000000.005000) can0 0123#00',
    '(1790000000.006000) can0 7#00',
]
PYTHON_CAN = [
    '(1790000000.000000) can0 311#0102030405060708 R',
    '(1790000000.001000) vcan0 18FF50E5#01 T',
    '(1790000000.002500) can0 300# r',
    '(1790000000.004000) can1 1FFFFFFF#aabbccddeeff0011 t',
    '(1790000000.005000) can0 0123#00 R',
    '(1790000000.006000) can0 7#00 R',
]
EXTENDED = [False, True, False, True, True, False]  # more than 3 digits
STYLES = {'candump': CANDUMP, 'python_can': PYTHON_CAN}
COMMON = CANDUMP
# Lines a chunk cannot take as common: python-can's reader decides each (a frame, a bad
# entry, a bad stamp, nothing), and the own reader must decide the same
ODD = [
    '(1790000000.010000) can0 123##1DEADBEEF',  # CAN FD, BRS
    '(1790000000.010000) can0 123##0' + '11' * 12,  # CAN FD, 12 bytes
    '(1790000000.010000) can0 123#R',  # remote
    '(1790000000.010000) can0 123#R8 R',  # remote with a length and a direction
    '(1790000000.010000) can0 20000080#0000000000000000',  # error frame (CAN_ERR_FLAG|BUSERROR)
    '(1790000000.010000) can0 20000004#00',  # the error flag without BUSERROR: masked
    '(1790000000.010000) can0 9FFFFFFF#01',  # the extended flag bit: masked
    '(1790000000.010000) can0 0123#01',  # four digits: extended
    '(1790000000.010000) can0 12#01',  # two digits: standard
    '(1790000000.010000) can0 0x1F#01',  # int(, 16) takes a 0x
    '(1790000000.010000) can0 1_F#01',  # and an underscore
    '(1790000000.010000) can0 123#+F',  # a data byte python-can parses as 0x0F
    '(1790000000.010000) can0 123#012',  # odd length: python-can's two bytes, DLC 1
    '(1790000000.010000) can0 123#' + '00' * 9,  # nine bytes: the DLC check
    '(1790000000.010000) can0 123#zz',  # garbled data
    '(1790000000.010000) can0 xyz#01',  # garbled ID
    '(1790000000.010000) can0',  # too few fields
    'garbage that is no frame at all',
    '(1790000000.010000) can0 123#01 R extra',  # too many fields
    '(1790000000.010000)  can0 123#01',  # two spaces
    '\t(1790000000.010000) can0 123#01',  # a tab before
    '(1790000000.010000) can0 123#01 ',  # a space after
    '(1790000000.010000)\tcan0\t123#01',  # tabs between
    '  ',
    '',
    '(nan) can0 123#01',
    '(inf) can0 123#01',
    '(1e308) can0 123#01',
    '(-1.5) can0 123#01',
    '(3000000000.000000) can0 123#01',  # past 2038
    '(1790000000) can0 123#01',  # no fraction: float() takes it
    '[1790000000.5] can0 123#01',  # python-can takes any first and last character
    '(1790000000.5)) can0 123#01',  # a parenthesis inside
    '(1_790_000_000.5) can0 123#01',
    '() can0 123#01',
    '(1790000000.010000) ca#n0 123#01',  # a '#' in the channel
    '(1790000000.010000) can0 123#01#02',  # two '#'
    '(1790000000.010000) can0 #01',  # no ID
    '(1790000000.010000) can0 123#01 X',  # a last field that is no direction
    '(1790000000.010000) can0 r',  # a frame that is a direction
    '(1790000000.010000) cän0 123#01',  # not ASCII
    '(1790000000.010000) ca\xa0n0 123#01',  # a space to str.split, not ASCII
    '(1790000000.010000) ca\u2028n0 123#01 R',  # a line break to str.split, not ASCII
    '(1790000000.010000) ca\tn0 123#01',  # a tab in a field
    '(1790000000.010000) can0 123#01\t02 R',  # bytes.fromhex would skip the tab
    '(1790000000.010000) can0 123#01\x0b02',
    '(1790000000.010000)  123#01',  # no channel
    '(1790000000.010000)  123#01 R',
    '(1790000000.010000) can0 123#01\x85',  # a line break to str.split, not to a file
    '(1790000000.010000) can0 123#01\x1c',  # whitespace to str.split
]


def write(path: Path, lines: list[str], end: str = '\n') -> Path:
    path.write_text(''.join(line + end for line in lines), encoding='utf-8')
    return path


def test_the_fixtures_hold_candump_logs():
    assert len(FIXTURE_LOGS) >= 10


@pytest.mark.parametrize('path', FIXTURE_LOGS, ids=lambda p: str(p.relative_to(FIXTURES)))
def test_every_fixture_log_reads_as_python_can_reads_it(path):
    got, found = read_both(path)
    assert got == bare_python_can(path)
    assert found == (0, '', 0, '', '', None)
    assert len(got) > 5


def test_a_real_candump_capture_is_parsed_without_python_can(monkeypatch):
    # fixtures/canbus_rs: 2,000 lines candump wrote of a BMS bus (interface elmcan, 'R')
    calls = []
    monkeypatch.setattr(candump_frames.CandumpFrames, '_python_can',
                        lambda self, line, out: calls.append(line))
    path = FIXTURES / 'canbus_rs' / 'bms_dump_excerpt.log'
    frames = LogFrames(str(path))
    got = [repr(frame) for frame in frames.frames()]
    assert calls == [] and counts(frames) == (0, '', 0, '', '', None)
    assert len(got) == 2000 and got == bare_python_can(path)
    # its first two lines, as the file has them
    assert got[:2] == [repr((1621945396.763904, 0x301, b'\x00\x00', False, False, False)),
                       repr((1621945396.78395, 0x321, bytes.fromhex('0000000004100408'),
                             False, False, False))]


@pytest.mark.parametrize('style', STYLES)
def test_common_lines_are_parsed_without_python_can(tmp_path, monkeypatch, style):
    calls = []
    monkeypatch.setattr(candump_frames.CandumpFrames, '_python_can',
                        lambda self, line, out: calls.append(line))
    path = write(tmp_path / 'common.log', STYLES[style] * 3000)
    frames = LogFrames(str(path))
    got = [repr(frame) for frame in frames.frames()]
    assert got == bare_python_can(path)
    assert [eval(frame)[3] for frame in got[:6]] == EXTENDED
    assert calls == [] and counts(frames) == (0, '', 0, '', '', None)


@pytest.mark.parametrize('style', STYLES)
def test_an_odd_line_goes_to_python_can_with_few_others(tmp_path, monkeypatch, style):
    calls = []
    python_can = candump_frames.CandumpFrames._python_can
    monkeypatch.setattr(candump_frames.CandumpFrames, '_python_can',
                        lambda self, line, out: calls.append(line) or python_can(self, line, out))
    lines = STYLES[style] * 1000 + [ODD[0]] + STYLES[style] * 1000
    got, _ = read_both(write(tmp_path / 'odd.log', lines))
    assert ODD[0] in calls and len(calls) <= candump_frames.LINES_ALONE
    assert len(got) == len(lines)


@pytest.mark.parametrize('style', STYLES)
def test_an_odd_line_among_common_ones_is_read_as_python_can_reads_it(tmp_path, monkeypatch,
                                                                      style):
    # chunks of ~90 lines: the odd line's chunk, not the first, is halved down to python-can
    monkeypatch.setattr(candump_frames, 'CHUNK', 4096)
    common = STYLES[style]
    for index, line in enumerate(ODD):  # the file's name says which line failed
        got, _ = read_both(write(tmp_path / f'odd{index}.log',
                                 common * 100 + [line] + common * 50))
        assert len(got) >= 150 * len(common), line


def test_every_odd_line_at_once_counts_as_python_can(tmp_path):
    got, (bad, last_bad, bad_stamps, *_) = read_both(write(tmp_path / 'all.log', ODD))
    assert bad >= 15 and bad_stamps == 5 and last_bad
    assert len(got) >= 10


@pytest.mark.parametrize('seed', range(4))
def test_random_mixes_of_common_and_odd_lines_read_as_python_can(tmp_path, seed):
    rng = random.Random(seed)
    for round in range(3):
        common = STYLES[rng.choice(list(STYLES))]
        share = rng.choice((0.0005, 0.01, 0.2))
        lines = [rng.choice(ODD) if rng.random() < share else rng.choice(common)
                 for _ in range(rng.randrange(1, 6000))]
        read_both(write(tmp_path / f'mix{seed}_{round}.log', lines, rng.choice(('\n', '\r\n'))))


def test_line_ends_as_a_text_file_has_them(tmp_path):
    for name, end in (('crlf', '\r\n'), ('cr', '\r')):
        got, _ = read_both(write(tmp_path / f'{name}.log', COMMON * 400, end))
        assert len(got) == len(COMMON) * 400, name


@pytest.mark.parametrize('last', [COMMON[0], COMMON[0][:30], ODD[0], '   ', '(1790000000.5'])
def test_a_cut_last_line_is_left_and_said_as_python_can_would(tmp_path, last):
    path = tmp_path / 'cut.log'
    path.write_text('\n'.join(COMMON * 300 + [last]), encoding='utf-8')
    got, (*_, truncated, cut_line) = read_both(path)
    assert len(got) == len(COMMON) * 300  # every line before the cut one
    assert cut_line == last and truncated.startswith('the log is cut short')


@pytest.mark.parametrize('text', ['', '\n\n  \n', COMMON[0], 'garbage\n' * 3])
def test_logs_without_a_common_line(tmp_path, text):
    path = tmp_path / 'few.log'
    path.write_text(text, encoding='utf-8')
    got, _ = read_both(path)
    assert len(got) <= 1


@pytest.mark.parametrize('where', [10, 3000])
def test_bytes_that_are_not_utf8_end_the_reading_where_python_cans_does(tmp_path, where):
    path = tmp_path / 'binary.log'
    lines = [line.encode() for line in COMMON * 800]
    lines.insert(where, b'(1790000000.5) can0 123#01\xff\xfe')
    path.write_bytes(b'\n'.join(lines) + b'\n')
    got, (bad, last_bad, *_) = read_both(path)
    assert bad == 1 and last_bad.startswith('UnicodeDecodeError')
    # python-can decodes 8 KiB at a time: the lines of the chunks before the bad one are read
    assert len(got) <= where and bool(got) == (where > 1000)


def test_a_garbled_line_mid_file_is_one_bad_entry(tmp_path):
    path = write(tmp_path / 'garbled.log', COMMON * 600 + ['(1790000000.5) can0 12$#01'] +
                 COMMON * 600)
    got, (bad, last_bad, bad_stamps, stopped, truncated, _) = read_both(path)
    assert (bad, bad_stamps, stopped, truncated) == (1, 0, '', '')
    assert last_bad.startswith('ValueError') and len(got) == len(COMMON) * 1200


def test_ids_the_reader_keeps_are_bounded(tmp_path, monkeypatch):
    monkeypatch.setattr(candump_frames, 'IDS_KEPT', 50)
    lines = [f'(1790000000.{k:06d}) can0 {k:08X}#01' for k in range(3000)]
    got, _ = read_both(write(tmp_path / 'ids.log', lines))
    assert [eval(frame)[1] for frame in got] == list(range(3000))
