# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ros/spinner.py: an executor's thread stopped without racing rclpy's shutdown."""
from __future__ import annotations

import threading
import time

from std_srvs.srv import Trigger
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
import rclpy.node

from ams_can_bridge.ros.spinner import Spinner, WAKE_S
from helpers import ros_context, wait_for


def test_stop_ends_the_loop_before_the_executor_is_shut_down_every_time():
    # rclpy's shutdown destroys the guard condition a thread inside spin() is about to wait
    # on (the demo died so at a stop: AttributeError, 'NoneType' object has no attribute
    # 'handle'). With executor.spin() on the thread and shutdown before the join, these
    # rounds fail.
    errors: list[BaseException] = []
    hook = threading.excepthook
    threading.excepthook = lambda args: errors.append(args.exc_value)
    try:
        with ros_context() as context:
            for round_ in range(60):
                node = rclpy.node.Node(f'spinner_test_{round_}', context=context)
                ticks: list[int] = []
                node.create_timer(0.001, lambda: ticks.append(1))
                executor = MultiThreadedExecutor(num_threads=2, context=context)
                executor.add_node(node)
                spinner = Spinner(executor, 'spinner-test')
                wait_for(lambda: len(ticks) > 0, timeout=5.0, what='a timer callback')
                assert spinner.stop(timeout=3.0)
                assert not spinner.thread.is_alive() and spinner.error is None
                node.destroy_node()
    finally:
        threading.excepthook = hook
    assert errors == []


def test_a_callback_that_raises_ends_the_loop_and_is_reported():
    seen: list[str] = []
    ended = threading.Event()
    with ros_context() as context:
        node = rclpy.node.Node('spinner_raise', context=context)

        def boom() -> None:
            raise RuntimeError('from a callback')
        node.create_timer(0.01, boom)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        spinner = Spinner(executor, 'spinner-raise',
                          on_error=lambda exc, trace: seen.append(f'{exc}|{"boom" in trace}'),
                          on_exit=ended.set)
        assert ended.wait(5.0)
        assert seen == ['from a callback|True'] and isinstance(spinner.error, RuntimeError)
        assert spinner.stop(timeout=3.0)
        node.destroy_node()


def test_an_idle_loop_sleeps_until_woken_and_a_stop_wakes_it():
    # Each timed-out wait rebuilds rclpy's wait set over all of a node's services (~0.9 ms of
    # CPU for the bridge's): a loop that woke 10 times a second cost ~1 % of a core, idle or
    # not (bench/README.md, issue 39). Idle, the loop waits; stop() wakes it at once.
    with ros_context() as context:
        node = rclpy.node.Node('spinner_idle', context=context)
        for k in range(20):  # services make each wait set dearer, as in the bridge
            node.create_service(Trigger, f'idle_{k}', lambda request, response: response)
        executor = MultiThreadedExecutor(num_threads=2, context=context)
        executor.add_node(node)
        waits: list[float] = []
        spin_once = executor.spin_once
        executor.spin_once = lambda timeout_sec=None: (  # type: ignore[method-assign]
            waits.append(time.monotonic()), spin_once(timeout_sec))
        spinner = Spinner(executor, 'spinner-idle')
        wait_for(lambda: len(waits) > 0, timeout=5.0, what='the first wait')
        time.sleep(1.0)  # within the first wait (WAKE_S, 2 s): a second of it is left
        idle_waits = len(waits)
        started = time.monotonic()
        assert spinner.stop(timeout=10.0)
        stopped_in = time.monotonic() - started
        node.destroy_node()
    # 0.1 s waits (the old loop) gave ~10 here; a wait of WAKE_S gives 1 (2 on a slow start)
    assert idle_waits <= 2, f'{idle_waits} waits in 1 s idle: the loop wakes on its own'
    # the stop's task ends the current wait: without it the stop waits out its last second
    assert stopped_in < WAKE_S / 4, f'the stop took {stopped_in:.2f} s'
