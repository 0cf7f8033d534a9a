# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""devices/timed.py: the one freshness store and the one counter-health rule of every device."""
import math

from ams_can_bridge.devices.timed import CounterHealth, NEVER, TimedSpans, TimedStore


def test_a_value_reads_as_absent_once_older_than_its_max_age():
    store = TimedStore()
    assert store.get('soc', 10.0, 1.0) is None and store.seen('soc') == NEVER
    store.put('soc', 77, 10.0)
    assert store.get('soc', 11.0, 1.0) == 77  # exactly max_age old: still fresh
    assert store.get('soc', 11.01, 1.0) is None
    assert store.latest('soc') == 77 and store.seen('soc') == 10.0  # whatever its age
    store.put('limits', (1, 2), 10.5)
    assert store.fresh(11.2, 1.0) == {'limits': (1, 2)}
    fresh, expired = store.split(11.2, lambda key: 5.0 if key == 'soc' else 0.5)
    assert fresh == {'soc': 77} and expired == {'limits': 11.2 - 10.5}


def test_a_span_whose_frame_stopped_reads_nan_and_its_neighbours_stay():
    spans = TimedSpans([2, 3])
    assert all(math.isnan(v) for v in spans.read(0.0, 1.0))
    spans.put(0, (1.0, 2.0), 0.0)
    spans.put(1, (3.0, 4.0, 5.0), 0.5)
    assert spans.read(1.0, 1.0) == [1.0, 2.0, 3.0, 4.0, 5.0]
    later = spans.read(1.2, 1.0)
    assert all(math.isnan(v) for v in later[:2]) and later[2:] == [3.0, 4.0, 5.0]
    assert spans.read(1.0, 1.0, spans=1) == [1.0, 2.0] and spans.read(1.0, 1.0, 0) == []
    assert spans.newest() == 0.5
    uniform = TimedSpans.uniform(4, 3)
    uniform.put(2, (9.0,) * 4, 0.0)
    assert uniform.read(0.0, 1.0)[8:] == [9.0] * 4 and len(uniform.read(0.0, 1.0)) == 12


def test_counter_repeats_skips_and_recovery():
    health = CounterHealth(0x100, recovery=3)
    health.observe(254, continuous=False)
    health.observe(255, continuous=True)
    assert not health.in_trouble
    health.observe(255, continuous=True)  # repeated: a stuck sender
    health.observe(255, continuous=True)
    assert health.repeat_run == 2 and health.repeats == 2 and health.in_trouble
    health.observe(1, continuous=True)  # 255 -> 1 across the wrap: counter 0 lost
    assert health.repeat_run == 0 and health.jumps == 1 and health.lost == 1
    for counter in (2, 3):
        health.observe(counter, continuous=True)
        assert health.in_trouble
    health.observe(4, continuous=True)  # the third good frame after the anomaly
    assert not health.in_trouble and health.lost == 1


def test_a_counter_restart_after_a_silence_is_no_anomaly():
    health = CounterHealth(0x10, recovery=16)
    health.observe(7, continuous=False)
    health.observe(7, continuous=True)
    assert health.repeat_run == 1
    health.observe(3, continuous=False)  # the previous frame had expired: sensor restarted
    assert health.repeat_run == 0 and health.jumps == 0 and health.lost == 0
    health.observe(4, continuous=True)
    assert health.jumps == 0


def test_a_learned_step_counts_lost_frames_and_steps_out_of_it():
    health = CounterHealth(0x10, recovery=2, step=None)  # counts 20 ms cycles, frames 100 ms
    for counter in (3, 8, 13):
        health.observe(counter, continuous=True)
    assert health.step == 5 and health.confirmed and not health.in_trouble
    health.observe(7, continuous=True)  # +10: one frame lost
    assert health.jumps == 1 and health.lost == 1 and health.in_trouble
    health.observe(9, continuous=True)  # +2: out of step, nothing lost
    assert health.jumps == 2 and health.lost == 1 and health.step == 5
    for counter in (14, 3):
        health.observe(counter, continuous=True)
    assert not health.in_trouble
    health.restart()  # the sender's rate changed: a new step is learned, no anomaly
    for counter in (4, 5, 6):
        health.observe(counter, continuous=True)
    assert health.step == 1 and health.jumps == 2 and not health.in_trouble
