# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
One engine: the same CAN log through the running bridge (replay) and through log2bag.

The log: the simulated AMS + IVT-S + BMS16 for 6 s of simulated time, with every frame of
1.5 s .. 4.5 s cut out, so every device goes silent (stale_timeout 1.5 s) and comes back.
The bridge replays it in real time (its periodic work on the wall clock; freshness, like
log2bag's, on the log's time); both feed the one ``Engine``. What must be equal, per topic:

- each ``<device>/battery_state`` with its arrays: every present message (header stamp,
  every value, the arrays' data), in order, and the silent spell as present: false
  messages with NaN arrays between the same two present messages;
- /diagnostics: the sequence of levels of every status (each change once), from the first
  message in which every device has been heard to the first that says the replay finished.

Collapsed, not counted: how many 1 Hz stale messages and periodic diagnostics fall into a
spell depends on where a real-time replay's wall-clock grid lands; what they say does not.
Trimmed: the moments before every device was first heard (the live bridge starts its watch
before its bus opens) and, live, after the replay finished (the bridge keeps running).
"""
from __future__ import annotations

import math

import can
import pytest
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray

from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.ros.demo_rig import build_simulators, device_parameters
from ams_can_bridge.sim.recording import write_log
from helpers import same, values_of
from shared import rosbags_read

DEVICES = ('ams', 'ivt_s', 'bms16')
ARRAYS = {'ams': ('temperatures', 'discharge_temperatures')}
START = 1_790_000_000.0
SECONDS = 6.0
GAP = (1.5, 4.5)  # s after the start: nothing on the bus
STALE_S = 1.5
STALE = 3  # diagnostic level
LEAD_IN = 2.0  # s of silence before the first device frame (see gap_log)
LEAD_IN_ID = 0x7FF  # no device of the test takes it


def parameters() -> dict:
    values = {'devices': list(DEVICES), 'diagnostics_period': 0.5,
              **{k: v for k, v in device_parameters(2).items() if k.split('.')[0] in DEVICES}}
    values.update({f'{name}.stale_timeout': STALE_S for name in DEVICES})
    return values


@pytest.fixture(scope='module')
def gap_log(tmp_path_factory) -> str:
    folder = tmp_path_factory.mktemp('equality')
    full = str(folder / 'full.log')
    write_log(full, list(build_simulators(2, DEVICES).values()), SECONDS, START)
    path = str(folder / 'gap.log')
    with can.LogReader(full) as reader, can.Logger(path) as writer:
        # A lead-in: one frame no device takes, LEAD_IN s before the first device frame, so
        # the test's subscriptions are matched (DDS discovery) before a real-time replay
        # publishes its first message; otherwise that message can be lost to the test.
        writer.on_message_received(can.Message(timestamp=START - LEAD_IN,
                                               arbitration_id=LEAD_IN_ID, data=b'',
                                               is_extended_id=False))
        for msg in reader:
            if not GAP[0] <= msg.timestamp - START < GAP[1]:
                writer.on_message_received(msg)
    return path


def stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def f32s(data) -> tuple:
    return tuple(float(v) for v in data)


def battery_tokens(batteries: list, arrays: dict[str, list]) -> list:
    """One token per message: present (stamp, values, arrays) or 'stale'; runs collapsed."""
    for suffix, msgs in arrays.items():
        assert len(msgs) == len(batteries), f'{suffix}: an array per BatteryState'
    tokens = []
    for k, msg in enumerate(batteries):
        data = tuple(f32s(arrays[s][k].data) for s in sorted(arrays))
        if msg.present:
            tokens.append(('present', round(stamp_ns(msg) / 1000), values_of(msg), data))
        else:
            assert all(math.isnan(v) for d in data for v in d), 'a stale array not NaN'
            assert math.isnan(msg.voltage)
            if not tokens or tokens[-1] != 'stale':
                tokens.append('stale')
    while tokens and tokens[0] == 'stale':  # before the first frame: trimmed (see above)
        tokens.pop(0)
    while tokens and tokens[-1] == 'stale':
        tokens.pop()
    return tokens


def level(status) -> int:
    return status.level if isinstance(status.level, int) else status.level[0]


def diagnostic_levels(arrays: list) -> dict:
    """
    Return each status's level sequence (changes only), trimmed as above.

    Per status, not per message: whether two devices go stale in the same /diagnostics
    message or in two depends on where the wall-clock watch ticks of a live replay land.
    """
    out: dict[str, list] = {}
    started = False
    for msg in arrays:
        levels = {s.name: level(s) for s in msg.status}
        values = {kv.key: kv.value for s in msg.status if s.name.endswith('CAN bus')
                  for kv in s.values}
        started = started or all(lv != STALE for name, lv in levels.items()
                                 if not name.endswith('CAN bus'))
        if started:
            for name, lv in levels.items():
                seq = out.setdefault(name, [])
                if not seq or seq[-1] != lv:
                    seq.append(lv)
        if values.get('replay') == 'finished':
            break
    return out


@pytest.mark.slow
def test_the_running_bridge_and_log2bag_emit_the_same_messages(gap_log, rig_factory,
                                                               tmp_path):
    bag = str(tmp_path / 'bag')
    convert(gap_log, bag, parameters())
    offline = {topic: [m for _, m in msgs] for topic, msgs in rosbags_read(bag).items()}

    topics = {f'{name}/battery_state': BatteryState for name in DEVICES}
    topics.update({f'{name}/{suffix}': Float32MultiArray
                   for name, suffixes in ARRAYS.items() for suffix in suffixes})
    live = rig_factory({**parameters(), 'can.interface': 'replay', 'can.channel': gap_log,
                        'can.replay_rate': 1.0}, topics=topics, depth=10000,
                       wait_connected=False)

    def finished() -> bool:
        return any(kv.key == 'replay' and kv.value == 'finished'
                   for m in live.messages('/diagnostics') for s in m.status for kv in s.values)
    live.wait(finished, LEAD_IN + SECONDS + 30.0, 'the replay to finish and be reported')

    for name in DEVICES:
        def tokens(source: dict, prefix: str) -> list:
            return battery_tokens(source[f'{prefix}{name}/battery_state'],
                                  {s: source[f'{prefix}{name}/{s}'] for s in ARRAYS.get(name, ())})
        got = tokens({t: live.messages(t) for t in topics}, '')
        want = tokens(offline, '/')
        assert 'stale' in want and sum(1 for t in want if t != 'stale') >= 4, name
        assert len(got) == len(want), (name, len(got), len(want))
        for k, (a, b) in enumerate(zip(got, want)):
            assert a == b if a == 'stale' or b == 'stale' else (
                a[:2] == b[:2] and same(a[2], b[2]) and same(a[3], b[3])), (name, k, a, b)

    got = diagnostic_levels(live.messages('/diagnostics'))
    want = diagnostic_levels(offline['/diagnostics'])
    assert any(STALE in seq for seq in want.values()), 'no stale spell seen'
    assert got == want
