# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""TimerThread: tasks on one thread, each at its own period; stop() wakes and joins it at once."""
import threading
import time

from ams_can_bridge.engine.timer import TimerThread
from helpers import assert_ended, wait_for


def test_tasks_run_at_their_periods_and_a_failing_one_does_not_stop_the_others():
    fast, slow = [], []

    def broken():
        raise RuntimeError('boom')

    periodic = TimerThread('test-periodic')
    periodic.every(0.02, lambda: fast.append(time.monotonic()))
    periodic.every(0.1, lambda: slow.append(time.monotonic()))
    periodic.every(0.02, broken)
    started = time.monotonic()
    periodic.start()
    thread = periodic._thread
    # the fast task goes on after the broken one has failed many times, the slow one runs too
    wait_for(lambda: len(fast) >= 10 and len(slow) >= 2, 10.0, 'both tasks to run')
    periodic.stop()
    count, slow_count = len(fast), len(slow)
    elapsed = time.monotonic() - started
    # each at its own period: never more often (a stalled thread skips slots, no burst)
    assert count <= elapsed / 0.02 + 1 and slow_count <= elapsed / 0.1 + 1
    assert count > slow_count
    assert_ended(thread, 'the periodic thread')
    assert len(fast) == count and len(slow) == slow_count  # stopped means stopped


def test_stop_wakes_a_thread_whose_next_task_is_an_hour_away():
    periodic = TimerThread('test-periodic')
    periodic.every(3600.0, lambda: None)
    periodic.start()
    thread = periodic._thread
    periodic.stop()
    # ended before stop() returned (it joins; its join would give up only after 5 s), though
    # its next task was an hour away: woken, not waited out
    assert not thread.is_alive()
    periodic.stop()  # idempotent


def test_restart_after_stop_and_stop_before_start():
    calls = []
    periodic = TimerThread('test-periodic')
    periodic.every(0.02, lambda: calls.append(1))
    periodic.stop()  # never started: nothing to do
    for _ in range(2):
        periodic.start()
        before = len(calls)
        wait_for(lambda: len(calls) >= before + 2, 5.0, 'two calls after the start')
        periodic.stop()


def test_stop_from_inside_a_task():
    periodic = TimerThread('test-periodic')
    done = threading.Event()
    calls = []

    def task():
        calls.append(1)
        periodic.stop()
        done.set()

    periodic.every(0.02, task)
    periodic.start()
    thread = periodic._thread
    assert done.wait(5.0)
    assert_ended(thread, 'the periodic thread')  # it returns after the task that stopped it
    assert len(calls) == 1
