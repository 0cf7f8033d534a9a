"""Helpers shared by the tests: hand-driven clock, polling, ROS context, DBC and codec checks."""
from __future__ import annotations

import contextlib
import logging
import time
from typing import Any, Callable, Iterator
import warnings

import canmatrix.formats
import cantools
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


def load_dbc_strictly(path: str, caplog: Any) -> tuple[Any, Any]:
    """
    Load a DBC in cantools (strict) and in canmatrix; fail on any warning of either.

    Return (the cantools database, the canmatrix matrix). caplog is pytest's fixture.
    """
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        db = cantools.database.load_file(path, strict=True)
        with caplog.at_level(logging.WARNING):
            matrix = canmatrix.formats.loadp_flat(path)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    return db, matrix
