# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag LOG... --output-dir DIR --jobs N: logs converted side by side, one bag per log.

Each log gets its own bag and summary; a broken log is named with its reason and the others
are converted all the same; the exit code says a log failed. The single-log form is kept.
"""
import os
import shutil

import pytest

from ams_can_bridge.offline.log2bag import main
from golden_bags import FOLDER
from shared import params_file, rosbags_read

LOG = str(FOLDER / 'car_mix.log')


@pytest.fixture
def logs(tmp_path):
    folder = tmp_path / 'logs'
    folder.mkdir()
    shutil.copy(LOG, folder / 'good.log')
    (folder / 'broken.log').write_text('this is no CAN log\nat all\n', encoding='utf-8')
    (folder / 'notes.txt').write_text('not a log: skipped in a folder', encoding='utf-8')
    return folder


@pytest.mark.process  # --jobs 2: worker processes
def test_two_logs_one_broken_side_by_side(tmp_path, logs, capsys):
    params = params_file(str(tmp_path / 'params.yaml'))
    out = tmp_path / 'bags'
    out.mkdir()
    single = str(tmp_path / 'single')
    assert main([LOG, single, '--params-file', params]) == 0  # the single-log form, kept
    capsys.readouterr()

    code = main([str(logs / 'broken.log'), str(logs / 'good.log'), '--output-dir', str(out),
                 '--params-file', params, '--jobs', '2'])
    printed = capsys.readouterr()
    assert code == 2
    assert sorted(os.listdir(out)) == ['good']  # the broken log left no bag
    assert 'broken.log' in printed.err and 'no CAN frame read' in printed.err
    assert '1 log(s) failed' in printed.err
    assert f'wrote {out / "good"} (mcap)' in printed.out and 'frames read: ' in printed.out
    assert '1 of 2 log(s) converted' in printed.out
    got = {topic: [t for t, _ in msgs] for topic, msgs in rosbags_read(str(out / 'good')).items()}
    want = {topic: [t for t, _ in msgs] for topic, msgs in rosbags_read(single).items()}
    assert got == want and sum(map(len, got.values())) > 100


@pytest.mark.process
def test_a_folder_of_logs_all_good_exits_0(tmp_path, logs, capsys):
    (logs / 'broken.log').unlink()
    shutil.copy(LOG, logs / 'second.log')
    params = params_file(str(tmp_path / 'params.yaml'))
    out = tmp_path / 'bags'
    out.mkdir()
    assert main([str(logs), '--output-dir', str(out), '--params-file', params]) == 0
    assert sorted(os.listdir(out)) == ['good', 'second']
    assert capsys.readouterr().out.count('frames read: ') == 2


@pytest.mark.parametrize('argv,words', [
    (['a.log', 'b.log', 'c.log'], '3 path(s) without --output-dir'),
    (['a.log', 'bag', '--jobs', '2'], '--jobs converts several logs'),
    (['a.log', '--output-dir', '.', '--jobs', '0'], '--jobs 0: give at least 1'),
])
def test_an_ambiguous_command_line_is_refused(argv, words, capsys, tmp_path):
    with pytest.raises(SystemExit) as caught:
        main(argv + ['--params-file', params_file(str(tmp_path / 'p.yaml'))])
    assert caught.value.code == 2
    assert words in capsys.readouterr().err


def test_two_logs_of_one_name_are_refused_before_any_work(tmp_path, capsys):
    for sub in ('day1', 'day2'):
        (tmp_path / sub).mkdir()
        shutil.copy(LOG, tmp_path / sub / 'run.log')
    out = tmp_path / 'bags'
    out.mkdir()
    code = main([str(tmp_path / 'day1' / 'run.log'), str(tmp_path / 'day2' / 'run.log'),
                 '--output-dir', str(out), '--params-file',
                 params_file(str(tmp_path / 'p.yaml'))])
    assert code == 2 and 'would both be converted into' in capsys.readouterr().err
    assert os.listdir(out) == []
