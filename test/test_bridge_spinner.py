# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ros/spinner.py: an executor's thread stopped without racing rclpy's shutdown."""
from __future__ import annotations

import threading

from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
import rclpy.node

from ams_can_bridge.ros.spinner import Spinner
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
