# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
CAN logs as the tools write them (issue 28 point 7): each reads whole, on its own timestamps.

The files in test/fixtures/logs (their README says where each comes from): candump -L as
can-utils writes it, can-utils' log2asc output (an .asc without Begin/End TriggerBlock, which
log2bag used to call "cut short"), asc2log's candump -L with direction flags, .asc in the
styles of Vector CANoe 10 (no trigger block) and 12, and .trc 1.1, 1.3, 2.0 and 2.1 in
PEAK's own layouts with their status, warning, error and event records. python-can's own
writers (.log, .asc, .blf, .csv) are test_log2bag.py's. Every timestamp below is worked out
by hand from the file: a .trc's $STARTTIME counts days from 1899-12-30 UTC (46286.5 is
2026-09-21 12:00:00 UTC = 1789992000) plus the offset in ms; an .asc's "date" line is local
time without a zone (so is python-can's reading of it, and CANoe's), plus the offset in s.
"""
from __future__ import annotations

from datetime import datetime
import os
from pathlib import Path
import shutil
import subprocess

import can
import pytest
import yaml

from ams_can_bridge.offline.log2bag import main
from ams_can_bridge.offline.log_frames import LogFrames
from shared import rosbags_read

LOGS = Path(__file__).parent / 'fixtures' / 'logs'
TRC_START = 1789992000.0  # $STARTTIME=46286.5 (days after 1899-12-30, UTC)
ASC_LOG2ASC = datetime(2026, 9, 21, 12, 0, 1).timestamp()  # "date Mon Sep 21 12:00:01 2026"
ASC_CANOE = datetime(2026, 9, 21, 14, 0, 0).timestamp()  # "date Mon Sep 21 02:00:00.000 pm"
# (AMS status 0x300 frames, BMS16 status 500 frames): the log times of the primary frames
# each file carries (the same bus moments in every file, as each tool words them)
SAME = ([TRC_START + 1.0, TRC_START + 1.300125], [TRC_START + 1.10025, TRC_START + 1.4])
FILES = {
    'candump_L.log': (SAME, 7, ()),
    'asc2log.log': (([1795707095.911730, 1795707096.211855],
                     [1795707096.011980, 1795707096.311730]), 7, ()),
    'log2asc.asc': (([ASC_LOG2ASC, ASC_LOG2ASC + 0.300125],
                     [ASC_LOG2ASC + 0.10025, ASC_LOG2ASC + 0.4]), 7, ()),
    'canoe_no_triggerblock.asc': (([ASC_CANOE + 1.0, ASC_CANOE + 1.300125],
                                   [ASC_CANOE + 1.10025, ASC_CANOE + 1.4]), 7, ()),
    'canoe_triggerblock.asc': (([ASC_CANOE + 1.0, ASC_CANOE + 1.300125],
                                [ASC_CANOE + 1.10025, ASC_CANOE + 1.4]), 7, ()),
    # 1.1 writes one decimal of a ms: 1100.2 and 1300.1
    'pcan_v1_1.trc': (([TRC_START + 1.0, TRC_START + 1.3001],
                       [TRC_START + 1.1002, TRC_START + 1.4]), 6, ('Error', 'Warng')),
    'pcan_v1_3.trc': (SAME, 6, ('Error', 'Warng')),
    'pcan_v2_0.trc': (SAME, 6, ('EC', 'ER', 'ST')),
    'pcan_v2_1.trc': (SAME, 6, ('EC', 'ER', 'EV', 'ST')),
}


def us(seconds: float) -> int:
    return round(seconds * 1e6)


@pytest.fixture(scope='module')
def params(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp('formats') / 'params.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': {
        'devices': ['ams', 'bms16'], 'ams': {'bank_count': 1}}}}))
    return str(path)


@pytest.mark.parametrize('name', sorted(FILES))
def test_every_entry_is_read_on_its_own_time(name):
    (ams, bms16), entries, others = FILES[name]
    frames = LogFrames(str(LOGS / name))
    try:
        messages = list(frames)
    finally:
        frames.close()
    assert (frames.bad, frames.stopped, frames.truncated) == (0, '', ''), frames.last_bad
    assert len(messages) == entries  # every frame, remote and error frames included
    assert sorted(frames.other_kinds) == list(others)  # the records that are no frame
    assert frames.other == len(others)  # one record of each kind in these files
    stamps = {aid: [us(m.timestamp) for m in messages if m.arbitration_id == aid
                    and not m.is_error_frame] for aid in (0x300, 500)}
    assert stamps == {0x300: [us(t) for t in ams], 500: [us(t) for t in bms16]}
    assert [bytes(m.data) for m in messages if m.arbitration_id == 0x18FF50E5] == \
        [bytes(range(1, 9))]
    assert [m.arbitration_id for m in messages if m.is_remote_frame] == [0x100]


@pytest.mark.parametrize('name', sorted(FILES))
def test_log2bag_converts_it_clean_on_its_times(name, params, tmp_path, capsys):
    (ams, bms16), _, others = FILES[name]
    out = str(tmp_path / 'bag')
    assert main([str(LOGS / name), out, '--params-file', params]) == 0
    printed = capsys.readouterr()
    assert printed.err == '', printed.err  # no warning: nothing is cut short
    assert 'bad log entries skipped: 0\n' in printed.out
    if others:
        assert f'records that are no frame skipped: {len(others)}' in printed.out
    bag = rosbags_read(out)
    for device, want in (('ams', ams), ('bms16', bms16)):
        got = [m.header.stamp.sec * 1_000_000 + round(m.header.stamp.nanosec / 1000)
               for _, m in bag[f'/{device}/battery_state'] if m.present]
        assert got == [us(t) for t in want], device


def test_can_utils_log2asc_writes_the_committed_file(tmp_path):
    """The fixture is can-utils' own output: made again here, byte for byte."""
    tool = shutil.which('log2asc')
    assert tool, 'log2asc not found: install can-utils (apt-get install can-utils; .ci/run does)'
    out = tmp_path / 'log2asc.asc'
    subprocess.run([tool, '-I', str(LOGS / 'candump_L.log'), '-O', str(out), 'can0'],
                   check=True, timeout=30, env={**os.environ, 'TZ': 'UTC'})
    assert out.read_bytes() == (LOGS / 'log2asc.asc').read_bytes()


def test_a_log_stamped_past_2038_is_refused_in_one_line(tmp_path, params, capsys):
    """python-can's own test BLFs carry 2459565876.494607 (year 2047): no ROS stamp holds it."""
    log = tmp_path / 'late.blf'
    with can.Logger(str(log)) as writer:
        for k in range(3):
            writer.on_message_received(can.Message(
                timestamp=2459565876.494607 + k, arbitration_id=0x300,
                data=bytes.fromhex('C021B423420100'), is_extended_id=False))
    assert main([str(log), str(tmp_path / 'bag'), '--params-file', params]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and 'Traceback' not in err
    assert 'no frame with a timestamp a ROS stamp can hold, 3 with one that is no time' in err
    assert '2459565878.494607: past 2038-01-19 03:14:07 UTC' in err, err
    assert not (tmp_path / 'bag').exists()
