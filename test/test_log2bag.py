# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag: CAN logs in several formats -> rosbag2, read back by two independent readers.

The log is written from the simulators in simulated time (timestamps far from now, so a
stamp taken from the host clock could not pass). What must hold, per format: every device
has exactly one battery_state per primary frame of the log, with the reference's values
(the real device classes fed the log without ROS, as for replay-equals-live), header stamp
and bag time equal to the frame's log timestamp to the microsecond; arrays come with each
battery_state; /diagnostics comes every diagnostics_period of log time (and early on a level
change, as live).
"""
import io
import os
import subprocess
import sys

import can
from mcap.reader import make_reader
import pytest
from rosbags.typesys import get_typestore, Stores

from ams_can_bridge.ros.demo_rig import build_simulators, device_parameters, DEVICES
from ams_can_bridge.offline.log2bag import convert, main, Progress
from ams_can_bridge.sim.recording import write_log
from helpers import device_reference, same, values_of
from shared import (BANKS, copy_as, DIAGNOSTICS_PERIOD, parameters, params_file, rosbags_read,
                    SECONDS)

ARRAYS = {'ams': ('temperatures', 'discharge_temperatures')}
STORE = get_typestore(Stores.ROS2_JAZZY)


@pytest.fixture(scope='module')
def base_log(tmp_path_factory) -> str:
    path = str(tmp_path_factory.mktemp('log2bag') / 'bus.log')
    frames = write_log(path, list(build_simulators(BANKS, DEVICES).values()), SECONDS)
    assert frames > 500
    return path


def mcap_read(bag: str) -> dict[str, list]:
    """Return (log_time ns, header stamp ns) per topic, read with the mcap library."""
    out: dict[str, list] = {}
    path = os.path.join(bag, next(f for f in os.listdir(bag) if f.endswith('.mcap')))
    with open(path, 'rb') as stream:
        for schema, channel, message in make_reader(stream).iter_messages():
            msg = STORE.deserialize_cdr(message.data, schema.name)
            stamp = msg.header.stamp if hasattr(msg, 'header') else None
            out.setdefault(channel.topic, []).append(
                (message.log_time, None if stamp is None
                 else stamp.sec * 1_000_000_000 + stamp.nanosec))
    return out


def us(seconds: float) -> int:
    return round(seconds * 1e6)


@pytest.mark.parametrize('fmt', ['log', 'blf', 'csv', 'asc'])
def test_bag_holds_what_the_bridge_publishes_on_log_time(base_log, tmp_path, fmt):
    log = base_log if fmt == 'log' else copy_as(base_log, str(tmp_path / f'bus.{fmt}'))
    bag = str(tmp_path / 'bag')
    summary = convert(log, bag, parameters())
    with can.LogReader(log) as reader:
        assert summary.frames_read == sum(1 for _ in reader)
    assert summary.bad_entries == 0 and not summary.stopped

    reference = device_reference(log, DEVICES, device_parameters(BANKS))
    topics = rosbags_read(bag)
    for name in DEVICES:
        want = reference[name]
        got = topics.get(f'/{name}/battery_state', [])
        assert len(want) >= 5, f'{name}: the log has only {len(want)} primary frames'
        assert len(got) == len(want), f'{fmt} {name}: {len(got)} messages, {len(want)} frames'
        for k, ((t_ns, msg), (stamp, values)) in enumerate(zip(got, want)):
            header_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            assert round(header_ns / 1000) == us(stamp) == round(t_ns / 1000), (name, k)
            assert same(values_of(msg), values), f'{fmt} {name} message {k} differs'
        for suffix in ARRAYS.get(name, ()):
            arrays = topics.get(f'/{name}/{suffix}', [])
            assert [t for t, _ in arrays] == [t for t, _ in got], (name, suffix)
            assert all(len(m.data) == m.layout.dim[0].size * m.layout.dim[1].size
                       for _, m in arrays)

    diagnostics = topics['/diagnostics']
    span = summary.last_stamp - summary.first_stamp
    first = summary.first_stamp
    # one per period of log time, plus the final one at the end of the log; besides them,
    # as live, one early at a watch (every 0.2 s of log time) whose levels changed
    grid = {us(first + (k + 1) * DIAGNOSTICS_PERIOD)
            for k in range(int(span / DIAGNOSTICS_PERIOD))}
    periodic = [round(t / 1000) for t, _ in diagnostics[:-1] if round(t / 1000) in grid]
    assert periodic == sorted(grid)
    early = [(t, m) for t, m in diagnostics[:-1] if round(t / 1000) not in grid]
    assert early, 'no early diagnostics: the first watch always sees new levels'
    levels = [tuple(s.level for s in m.status) for _, m in diagnostics[:-1]]
    for t, msg in early:
        k = next(i for i, (u, _) in enumerate(diagnostics) if u == t)
        assert k == 0 or levels[k] != levels[k - 1], 'an early diagnostics without a change'
        assert round((t / 1e9 - first) / 0.2, 3) % 1 == 0, 'early, off the watch grid'
    names = {s.name for s in diagnostics[-1][1].status}
    assert names == {f'ams_can_bridge: {n}' for n in (*DEVICES, 'CAN bus')}
    bus = {kv.key: kv.value for s in diagnostics[-1][1].status if s.name.endswith('CAN bus')
           for kv in s.values}
    assert bus['frames in'] == str(summary.frames_read) and bus['replay'] == 'finished'

    # the mcap library, independently: same counts, log_time = header stamp
    raw = mcap_read(bag)
    assert {t: len(v) for t, v in raw.items()} == {t: len(v) for t, v in topics.items()}
    for topic, entries in raw.items():
        if topic.endswith('battery_state'):
            assert all(log_time == stamp for log_time, stamp in entries), topic


def test_start_end_window_and_sqlite3(base_log, tmp_path):
    bag = str(tmp_path / 'window')
    summary = convert(base_log, bag, parameters(), storage='sqlite3', start=2.0, end=4.0)
    reference = device_reference(base_log, DEVICES, device_parameters(BANKS))
    t0 = min(seq[0][0] for seq in reference.values())
    topics = rosbags_read(bag)
    assert os.path.exists(os.path.join(bag, 'window.db3'))
    for name in DEVICES:
        want = [(s, v) for s, v in reference[name] if 2.0 <= s - t0 <= 4.0]
        got = topics[f'/{name}/battery_state']
        assert [round(t / 1000) for t, _ in got] == [us(s) for s, _ in want], name
        # decoded from the start: the first message in the window has the full state
        assert same(values_of(got[0][1]), want[0][1]), name
    assert 1.9 <= summary.last_stamp - summary.first_stamp <= 2.0


def test_bad_lines_are_counted_and_skipped(base_log, tmp_path):
    lines = open(base_log, encoding='utf-8').read().splitlines(True)
    bad = [10, 200, 201]
    for k in bad:
        lines[k] = '(1790000000.5) vcan0 12G#ZZ\n'
    log = tmp_path / 'damaged.log'
    log.write_text(''.join(lines), encoding='utf-8')
    summary = convert(str(log), str(tmp_path / 'bag'), parameters())
    assert summary.bad_entries == len(bad)
    assert summary.frames_read == len(lines) - len(bad)


def test_unusable_input_exits_2_with_a_clear_message(base_log, tmp_path, capsys):
    params = params_file(str(tmp_path / 'params.yaml'))
    cases = [
        ([str(tmp_path / 'missing.log'), str(tmp_path / 'a'), '--params-file', params],
         'does not exist'),
        ([str(tmp_path / 'params.yaml'), str(tmp_path / 'b'), '--params-file', params],
         'python-can reads'),
        ([base_log, str(tmp_path), '--params-file', params], 'exists'),
        ([base_log, str(tmp_path / 'c'), '--params-file', str(tmp_path / 'none.yaml')],
         'none.yaml'),
    ]
    for argv, words in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith('log2bag: ') and words in err, (argv, err)
        assert 'Traceback' not in err
    bad = tmp_path / 'bad.yaml'
    bad.write_text("/**:\n  ros__parameters:\n    devices: [ams]\n    ams:\n"
                   "      bank_count: 99\n", encoding='utf-8')
    assert main([base_log, str(tmp_path / 'd'), '--params-file', str(bad)]) == 2
    err = capsys.readouterr().err
    assert 'ams.bank_count = 99 is out of range' in err, err
    assert not os.path.exists(tmp_path / 'd'), 'a refused conversion leaves no bag behind'


def test_command_runs_without_ros_and_prints_a_summary(base_log, tmp_path):
    params = params_file(str(tmp_path / 'params.yaml'))
    bag = str(tmp_path / 'bag')
    code = ('import sys\nfrom ams_can_bridge.offline.log2bag import main\n'
            f'rc = main([{base_log!r}, {bag!r}, "--params-file", {params!r}])\n'
            'assert "rclpy" not in sys.modules, "log2bag imported rclpy"\nsys.exit(rc)\n')
    env = {k: v for k, v in os.environ.items() if not k.startswith(('ROS_', 'RMW_'))}
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=60, env=env)
    assert done.returncode == 0, done.stderr
    assert 'frames read: ' in done.stdout and '/ams/battery_state: ' in done.stdout
    assert os.path.exists(os.path.join(bag, 'metadata.yaml'))


class Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_on_a_terminal_only():
    tty = Tty()
    bar = Progress(1000, tty)
    bar.update(250, force=True)
    bar.finish(1000)
    text = tty.getvalue()
    assert '250 of ~1,000 frames' in text and 's left' in text and text.endswith('\n')
    quiet = io.StringIO()
    Progress(1000, quiet).finish(1000)
    assert quiet.getvalue() == ''
