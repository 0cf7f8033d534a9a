# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Log timestamps that are no time, and gaps of days (issue 26 point 6), in log2bag and a replay.

A red team's logs made log2bag run forever (a NaN or infinite timestamp; a gap of days wrote
a stale message per device per second of it), end in a traceback (a timestamp past 2038,
which a ROS stamp cannot hold), and a replay stamp frames with the host clock or a year
wrapped to 1985. Now: an entry whose timestamp is no time is a bad log entry (counted,
skipped); a gap writes what a silence changes (each device going stale, once) and not one
message per second of it; every stamp written is one of the log's.

log2bag runs as a subprocess with a timeout: a conversion that never ends fails the test
instead of hanging it. The log's valid moments are in 2030, far from any host clock.
"""
from __future__ import annotations

import math
import subprocess
import sys
import time

import can
from diagnostic_msgs.msg import DiagnosticArray

from ams_can_bridge.bus_state import BusState
from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.offline.converter import Converter
from ams_can_bridge.ros.demo_rig import build_simulators, DEVICES
from ams_can_bridge.sim.recording import write_log
from command_rig import battery_topics
from shared import DIAGNOSTICS_PERIOD, params_file, parameters, rosbags_read

START = 1_900_000_000.0  # 2030-03-17
GAP = 3 * 86400.0  # s: a car parked for three days
# Entries with a timestamp that is no time, each with a frame every device would take
BAD_STAMPS = ['nan', 'inf', '-inf', '-1.500000', '2147483648.000000', '2200000000.000000']
TIMEOUT = 120  # s for one log2bag run (a few s normally; "forever" without the fix)


def sim_log(path: str, seconds: float, start: float = START) -> list[str]:
    """Return the candump lines of the simulated devices for seconds from start."""
    write_log(path, list(build_simulators(2, DEVICES).values()), seconds, start)
    with open(path, encoding='ascii') as stream:
        return stream.readlines()


def with_bad_stamps(lines: list[str]) -> list[str]:
    """Put a bad-timestamp copy of a real line after every tenth of the log."""
    out = list(lines)
    step = len(lines) // (len(BAD_STAMPS) + 1)
    for k, stamp in reversed(list(enumerate(BAD_STAMPS, 1))):
        frame = lines[k * step].split(') ', 1)[1]  # 'can0 300#C021...'
        out.insert(k * step + 1, f'({stamp}) {frame}')
    return out


def run_log2bag(log: str, out: str, params: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, '-m', 'ams_can_bridge.offline.log2bag', log, out, '--params-file',
         params], capture_output=True, text=True, timeout=TIMEOUT)


def ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def test_log2bag_skips_entries_whose_timestamp_is_no_time(tmp_path):
    lines = sim_log(str(tmp_path / 'good.log'), 2.0)
    log = tmp_path / 'bad_stamps.log'
    log.write_text(''.join(with_bad_stamps(lines)), encoding='ascii')
    out = str(tmp_path / 'bag')
    done = run_log2bag(str(log), out, params_file(str(tmp_path / 'params.yaml')))
    assert done.returncode == 0, done.stderr
    assert 'Traceback' not in done.stderr
    assert f'bad log entries skipped: {len(BAD_STAMPS)} (last: frame 0x' in done.stdout
    assert 'past 2038-01-19 03:14:07 UTC' in done.stdout, done.stdout
    first, last = START, float(lines[-1][1:].split(')')[0])
    for topic, messages in rosbags_read(out).items():
        for t_ns, msg in messages:
            assert first * 1e9 - 1 <= t_ns <= last * 1e9 + 1, (topic, t_ns)
            if hasattr(msg, 'header'):
                assert ns(msg.header.stamp) == t_ns, topic


def test_a_gap_of_days_writes_each_device_going_stale_once(tmp_path):
    before = sim_log(str(tmp_path / 'a.log'), 3.0)
    after = sim_log(str(tmp_path / 'b.log'), 3.0, START + GAP)
    log = tmp_path / 'gap.log'
    log.write_text(''.join(before + after), encoding='ascii')
    out = str(tmp_path / 'bag')
    done = run_log2bag(str(log), out, params_file(str(tmp_path / 'params.yaml')))
    assert done.returncode == 0, done.stderr
    gap_start, gap_end = START + 3.0, START + GAP
    bag = rosbags_read(out)
    # every device stale and noticed: the longest stale_timeout and two watch periods
    horizon = Converter(parameters(), None, 'x').engine.quiet_horizon()
    for name in DEVICES:
        silent = [t for t, m in bag[f'/{name}/battery_state']
                  if gap_start * 1e9 <= t < gap_end * 1e9]
        assert silent, f'{name}: its going stale is written'
        assert all(not m.present for t, m in bag[f'/{name}/battery_state']
                   if gap_start * 1e9 <= t < gap_end * 1e9)
        assert len(silent) == 1, f'{name}: {len(silent)} present: false in the gap'
    diagnostics = [t for t, _ in bag['/diagnostics'] if gap_start * 1e9 <= t < gap_end * 1e9]
    # the periodic ones while the devices go stale, and the early ones of each change
    assert len(diagnostics) <= horizon / DIAGNOSTICS_PERIOD + 1 + 2 * len(DEVICES)
    assert all(t <= (gap_start + horizon) * 1e9 for t in diagnostics), 'later into the gap'
    # the second part is written as the first: a message per primary frame, on its time
    assert [t for t, m in bag['/ams/battery_state'] if t >= gap_end * 1e9 and m.present]


# --- the replay ------------------------------------------------------------------------------
def test_a_replay_skips_them_and_stamps_only_with_the_log(tmp_path):
    lines = with_bad_stamps(sim_log(str(tmp_path / 'good.log'), 1.0))
    log = tmp_path / 'bad_stamps.log'
    log.write_text(''.join(lines), encoding='ascii')
    with can.LogReader(str(log)) as reader:
        valid = [m.timestamp for m in reader if 0 <= m.timestamp < 2 ** 31]
    got: list[float] = []
    io = CanIo(BusConfig(interface='replay', channel=str(log), replay_rate=0.0),
               lambda aid, data, ext, stamp: got.append(stamp))
    io.start()
    try:
        end = time.monotonic() + 10.0
        while io.status().state != BusState.REPLAY_FINISHED and time.monotonic() < end:
            time.sleep(0.02)
        status = io.status()
    finally:
        io.stop()
    assert status.state == BusState.REPLAY_FINISHED
    assert got == valid, 'every frame with a usable timestamp, stamped with it, in order'
    assert status.frames_unreadable == len(BAD_STAMPS)
    assert f'{len(BAD_STAMPS)} entries skipped, their timestamp no time' in status.reason
    assert io.last_stamp == valid[-1]


def test_the_replaying_bridge_stamps_every_message_with_the_log(rig_factory, tmp_path):
    """Diagnostics and stale messages too: the log's first moment before its first frame."""
    lines = with_bad_stamps(sim_log(str(tmp_path / 'good.log'), 1.0))
    log = tmp_path / 'bad_stamps.log'
    log.write_text(''.join(lines), encoding='ascii')
    values = {**parameters(), 'can.interface': 'replay', 'can.channel': str(log),
              'can.replay_rate': 2.0}
    rig = rig_factory(values, wait_connected=False, depth=10000,
                      topics={**battery_topics(DEVICES), '/diagnostics': DiagnosticArray})
    rig.wait(lambda: rig.node.can_io.status().state == 'replay finished', 20.0,
             'the replay to finish')
    rig.wait(lambda: any(values_of(m).get('state') == 'replay finished'
                         for m in rig.messages('/diagnostics')), 10.0,
             'the diagnostics that say the replay finished')
    rig.close()
    last = float(lines[-1][1:].split(')')[0])
    stamps = [ns(m.header.stamp) for name in DEVICES
              for m in rig.messages(f'{name}/battery_state')]
    stamps += [ns(m.header.stamp) for m in rig.messages('/diagnostics')]
    assert stamps and all(START * 1e9 - 1 <= s <= last * 1e9 + 1 for s in stamps), \
        [s / 1e9 for s in stamps if not START * 1e9 - 1 <= s <= last * 1e9 + 1][:5]
    bus = [values_of(m) for m in rig.messages('/diagnostics')][-1]
    assert bus['unreadable frames'] == str(len(BAD_STAMPS))


def values_of(msg: DiagnosticArray) -> dict[str, str]:
    """Return the CAN bus status's values of a DiagnosticArray ({} without it)."""
    for status in msg.status:
        if status.name.endswith('CAN bus'):
            return {kv.key: kv.value for kv in status.values}
    return {}


def test_the_bound_is_the_last_second_a_ros_stamp_holds():
    from ams_can_bridge.can_io.replay import stamp_problem
    assert stamp_problem(2 ** 31 - 1e-6) == '' and stamp_problem(0.0) == ''
    assert all(stamp_problem(s) for s in (2 ** 31, math.nan, math.inf, -math.inf, -1e-9))


def test_the_schedule_runs_into_a_gap_up_to_its_horizon_and_restarts_after_a_step_back():
    from ams_can_bridge.engine.core import Schedule
    runs: list[tuple[str, float]] = []
    now = [0.0]
    schedule = Schedule([(1.0, lambda: runs.append(('slow', now[0]))),
                         (0.2, lambda: runs.append(('fast', now[0])))],
                        lambda t: now.__setitem__(0, t), horizon=2.0)
    schedule.start(100.0)
    schedule.run_until(100.0 + GAP)  # three days later
    assert max(t for _, t in runs) <= 102.0 + 1e-9  # worked through 2 s of it, no more
    assert 2 + 9 <= len(runs) <= 2 + 10  # float steps: 102.00000000000003 is past 102
    runs.clear()
    schedule.run_until(100.0 + GAP + 1.0)
    # on its own grid again after the gap: the whole seconds of the start
    assert [t for k, t in runs if k == 'slow'] == [100 + GAP, 101 + GAP]
    assert all(100 + GAP <= t <= 101 + GAP for _, t in runs)
    runs.clear()
    schedule.run_until(50.0)  # an earlier log put after this one: the grid starts there
    schedule.run_until(51.0)
    assert [k for k, _ in runs][:5] == ['fast'] * 4 + ['slow'], runs
    assert all(50 < t <= 51 + 1e-9 for _, t in runs)
