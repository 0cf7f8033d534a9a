"""Periodic: tasks on one thread, each at its own period; stop() wakes and joins it at once."""
import threading
import time

from ams_can_bridge.periodic import Periodic


def test_tasks_run_at_their_periods_and_a_failing_one_does_not_stop_the_others():
    fast, slow = [], []

    def broken():
        raise RuntimeError('boom')

    periodic = Periodic('test-periodic')
    periodic.every(0.02, lambda: fast.append(time.monotonic()))
    periodic.every(0.1, lambda: slow.append(time.monotonic()))
    periodic.every(0.02, broken)
    periodic.start()
    time.sleep(0.35)
    periodic.stop()
    assert 3 <= len(fast) <= 18 and 1 <= len(slow) <= 4  # loose: a loaded machine stalls
    count = len(fast)
    time.sleep(0.1)
    assert len(fast) == count  # stopped means stopped


def test_stop_wakes_a_thread_whose_next_task_is_an_hour_away():
    periodic = Periodic('test-periodic')
    periodic.every(3600.0, lambda: None)
    periodic.start()
    thread = periodic._thread
    started = time.monotonic()
    periodic.stop()
    assert time.monotonic() - started < 1.0
    assert not thread.is_alive()
    periodic.stop()  # idempotent


def test_restart_after_stop_and_stop_before_start():
    calls = []
    periodic = Periodic('test-periodic')
    periodic.every(0.02, lambda: calls.append(1))
    periodic.stop()  # never started: nothing to do
    for _ in range(2):
        periodic.start()
        deadline = time.monotonic() + 2.0
        before = len(calls)
        while len(calls) < before + 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        periodic.stop()
        assert len(calls) >= before + 2


def test_stop_from_inside_a_task():
    periodic = Periodic('test-periodic')
    done = threading.Event()
    calls = []

    def task():
        calls.append(1)
        periodic.stop()
        done.set()

    periodic.every(0.02, task)
    periodic.start()
    assert done.wait(2.0)
    time.sleep(0.1)
    assert len(calls) == 1
