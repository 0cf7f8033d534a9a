"""Helpers shared by the tests: a hand-driven clock, polling, a ROS context, frame fuzzing."""
from __future__ import annotations

import contextlib
import time
from typing import Callable, Iterator

import rclpy
from rclpy.context import Context

from ams_can_bridge.protocols.common import MalformedFrameError


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


def assert_decodes_or_malformed(codec: object, frame_id: int, data: bytes) -> None:
    """Assert that codec reads the frame, or refuses it with a MalformedFrameError naming it."""
    try:
        reading = codec.decode(frame_id, data)
    except MalformedFrameError as exc:
        assert exc.arbitration_id == frame_id, (exc.arbitration_id, frame_id)
    else:
        assert reading is not None, f'0x{frame_id:X} {data.hex()} decoded to None'
