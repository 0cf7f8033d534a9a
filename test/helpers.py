"""Helpers shared by the tests: a hand-driven clock, polling with a timeout, a ROS context."""
from __future__ import annotations

import contextlib
import time
from typing import Callable, Iterator

import rclpy
from rclpy.context import Context


class Clock:
    """A hand-driven monotonic clock, so staleness is tested without sleeping."""

    def __init__(self, now: float = 100.0) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now


def wait_for(predicate: Callable[[], object], timeout: float = 5.0,
             what: str = 'condition') -> None:
    """Poll predicate until true; fail the test naming what did not happen."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.01)
    raise AssertionError(f'timed out after {timeout} s waiting for {what}')


@contextlib.contextmanager
def ros_context() -> Iterator[Context]:
    """Yield an initialised rclpy context of its own; shut it down afterwards."""
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)
