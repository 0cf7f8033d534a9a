# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's failures (issue 18.8): each is one line on stderr and exit 2, and leaves no bag.

A log cut short is converted up to where it stops and says where; a .trc full of lines its
reader cannot parse gives one summary line, not one warning per line.
"""
import os
from pathlib import Path
import subprocess
import sys
import xml.etree.ElementTree as ET

import can
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
import yaml

from ams_can_bridge.offline.log2bag import main
from ams_can_bridge.ros.demo_rig import build_simulators, DEVICES
from ams_can_bridge.sim.recording import write_log
from shared import BANKS, copy_as, params_file, SECONDS

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture(scope='module')
def base_log(tmp_path_factory) -> str:
    path = str(tmp_path_factory.mktemp('log2bag_failures') / 'bus.log')
    assert write_log(path, list(build_simulators(BANKS, DEVICES).values()), SECONDS) > 500
    return path


@pytest.fixture
def params(tmp_path) -> str:
    return params_file(str(tmp_path / 'params.yaml'))


def fails(argv: list[str], capsys) -> str:
    """Run log2bag; assert exit 2 with one line and no traceback; return that line."""
    assert main(argv) == 2, argv
    err = capsys.readouterr().err
    assert err.startswith('log2bag: ') and err.count('\n') == 1, err
    assert 'Traceback' not in err
    return err


def test_start_past_the_end_of_the_log_is_exit_2_and_leaves_no_bag(
        base_log, params, tmp_path, capsys):
    out = str(tmp_path / 'late')
    err = fails([base_log, out, '--params-file', params, '--start', '100'], capsys)
    assert '--start 100 s is past the end of the log' in err and 'span 5.9' in err, err
    assert not os.path.exists(out)


def test_an_output_that_exists_or_cannot_be_created_is_exit_2(base_log, params, tmp_path,
                                                              capsys):
    (tmp_path / 'file').write_text('x')
    locked = tmp_path / 'locked'
    locked.mkdir()
    locked.chmod(0o500)
    cases = [(str(tmp_path / 'no' / 'such' / 'bag'), 'does not exist'),
             (str(tmp_path / 'file' / 'bag'), 'is not a directory'),
             (str(tmp_path / 'file'), 'exists')]
    if os.geteuid() != 0:  # root writes anywhere
        cases.append((str(locked / 'bag'), 'no permission to write'))
    for out, words in cases:
        err = fails([base_log, out, '--params-file', params], capsys)
        assert f'{out!r}' in err and words in err, err
    assert sorted(os.listdir(tmp_path)) == ['file', 'locked', 'params.yaml']
    assert os.listdir(locked) == []


def test_a_bag_the_writer_cannot_create_leaves_nothing(
        base_log, params, tmp_path, capsys, monkeypatch):
    """A failure of the writer itself (here: a storage it refuses) is one line too."""
    from ams_can_bridge.offline import bag as bag_module
    monkeypatch.setitem(bag_module.STORAGES, 'mcap', 'no-such-plugin')
    out = str(tmp_path / 'bag')
    err = fails([base_log, out, '--params-file', params], capsys)
    assert f'cannot create the bag {out!r}' in err, err
    assert not os.path.exists(out)


def test_rosbags_missing_says_how_to_install_it(base_log, params, tmp_path):
    out = str(tmp_path / 'bag')
    code = ('import sys\nsys.modules["rosbags"] = None  # as if not installed\n'
            'from ams_can_bridge.offline.log2bag import main\n'
            f'sys.exit(main([{base_log!r}, {out!r}, "--params-file", {params!r}]))\n')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count('\n') == 1 and 'Traceback' not in done.stderr, done.stderr
    assert 'pip install rosbags' in done.stderr and 'python3-rosbags-pip' in done.stderr
    assert not os.path.exists(out)
    # ... and a ROS workspace install declares it (the rosdep key of ros/rosdistro)
    depends = [e.text for e in ET.parse(os.path.join(ROOT, 'package.xml')).getroot()
               if e.tag == 'exec_depend']
    assert 'python3-rosbags-pip' in depends


def test_a_file_that_is_not_a_can_log_or_an_empty_log_is_exit_2(base_log, params, tmp_path,
                                                                capsys):
    empty = tmp_path / 'empty.log'
    empty.write_text('')
    yaml_as_log = tmp_path / 'params.log'
    yaml_as_log.write_text(open(params).read())
    lines = open(base_log).read().splitlines(True)
    mostly_bad = tmp_path / 'mostly_bad.log'  # 10 frames, then 40 lines of garbage
    mostly_bad.write_text(''.join(lines[:10]) + 'garbage that is no frame\n' * 40)
    cases = [(empty, 'holds no CAN frame (empty)'),
             (yaml_as_log, 'no CAN frame read'),
             (mostly_bad, 'most entries are unreadable (40 of 50)')]
    for log, words in cases:
        out = str(tmp_path / f'bag_{log.stem}')
        err = fails([str(log), out, '--params-file', params], capsys)
        assert words in err, err
        assert 'is it a CAN log' in err or log == empty, err
        assert not os.path.exists(out), log


@pytest.mark.parametrize('fmt', ['blf', 'asc', 'log'])
def test_a_truncated_log_says_where_it_stopped(base_log, params, tmp_path, capsys, fmt):
    whole = copy_as(base_log, str(tmp_path / f'whole.{fmt}')) if fmt != 'log' else base_log
    data = open(whole, 'rb').read()
    cut = tmp_path / f'cut.{fmt}'
    cut.write_bytes(data[:len(data) // 2 + 7])  # mid-line / mid-object
    out = str(tmp_path / 'bag')
    assert main([str(cut), out, '--params-file', params]) == 0
    captured = capsys.readouterr()
    warning = [line for line in captured.err.splitlines() if line.startswith('log2bag:')]
    assert len(warning) == 1 and 'the log is cut short' in warning[0], captured.err
    assert 'stopped after frame ' in warning[0] and 'log time +' in warning[0]
    assert 'the log is cut short' in captured.out  # in the summary too
    if fmt != 'blf':  # the cut line is left out, not read as a frame with part of its data
        assert 'its last line has no end and was not read' in warning[0]
        assert 'malformed' not in captured.out, captured.out


def test_a_whole_log_is_not_called_truncated(base_log, params, tmp_path, capsys):
    for fmt in ('blf', 'asc'):
        log = copy_as(base_log, str(tmp_path / f'whole.{fmt}'))
        assert main([log, str(tmp_path / f'bag_{fmt}'), '--params-file', params]) == 0
        captured = capsys.readouterr()
        assert 'cut short' not in captured.out + captured.err


def test_trc_parse_errors_are_one_summary_line(base_log, params, tmp_path, capfd):
    trc = copy_as(base_log, str(tmp_path / 'bus.trc'))
    lines = open(trc).read().splitlines(True)
    # lines cut after the channel: python-can's reader logs a warning for each and goes on
    damaged = [line.split(' Rx ')[0] + '\n' if ' Rx -  8 ' in line else line
               for line in lines]
    bad = sum(1 for a, b in zip(lines, damaged) if a != b)
    assert bad > 50
    log = tmp_path / 'damaged.trc'
    log.write_text(''.join(damaged))
    assert main([str(log), str(tmp_path / 'bag'), '--params-file', params]) == 0
    captured = capfd.readouterr()
    assert 'Failed to parse' not in captured.err, captured.err[:500]
    assert f'bad log entries skipped: {bad} (last: TRCReader: Failed to parse' in captured.out
    # the reader's own logger is as it was afterwards
    assert can.io.trc.logger.level == 0 and not can.io.trc.logger.filters


def test_a_node_name_with_a_namespace_names_the_statuses_as_the_bridge(base_log, tmp_path):
    """Issue 18.4 offline: --node-name car2/ams_can_bridge gives 'car2/ams_can_bridge: ...'."""
    with open(params_file(str(tmp_path / 'all.yaml'))) as stream:
        values = yaml.safe_load(stream)['/**']
    (tmp_path / 'cars.yaml').write_text(yaml.safe_dump({'/car2/ams_can_bridge': values}))
    out = tmp_path / 'bag'
    assert main([base_log, str(out), '--params-file', str(tmp_path / 'cars.yaml'),
                 '--node-name', 'car2/ams_can_bridge', '--end', '2']) == 0
    names = set()
    with AnyReader([Path(out)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as bag:
        for connection, _, raw in bag.messages():
            if connection.topic == '/diagnostics':
                names |= {s.name for s in bag.deserialize(raw, connection.msgtype).status}
    assert names and all(n.startswith('car2/ams_can_bridge: ') for n in names), names
    assert 'car2/ams_can_bridge: CAN bus' in names
