"""
What several test files share: fakes that stand in for a bus or a log, and golden data.

Golden frames and configurations are written by hand from the vendors' sources (each file
that defines them says which); test files import them from here, never from one another.
"""
from __future__ import annotations

import logging
import threading
from typing import Callable

from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.errors import CanSendError
from ams_can_bridge.protocols.common import Frame


class FakeBus:
    """A bus whose state the test sets (the gate's ``BusPort``); records every frame sent."""

    def __init__(self, state: BusState = BusState.CONNECTED) -> None:
        self.state = state
        self.reason = ''
        self.sent: list[Frame] = []
        self.fail = ''  # set: every send fails with it (CanSendError)
        self.before_send: Callable[[Frame], None] | None = None  # called before each send
        self.cv = threading.Condition()

    def set_state(self, state: BusState, reason: str = '') -> None:
        with self.cv:
            self.state, self.reason = state, reason
            self.cv.notify_all()

    def status(self) -> BusStatus:
        return BusStatus(self.state, self.reason, 0, len(self.sent), 0, 0, 0, 'fake:0')

    def wait_connected(self, timeout: float) -> BusStatus:
        with self.cv:
            self.cv.wait_for(lambda: self.state == BusState.CONNECTED, timeout)
        return self.status()

    def send(self, frame: Frame) -> None:
        if self.before_send is not None:
            self.before_send(frame)
        if self.fail:
            raise CanSendError(self.fail)
        self.sent.append(frame)


class Lines(logging.Handler):
    """Collect log records as (level, text)."""

    def __init__(self) -> None:
        super().__init__()
        self.lines: list[tuple[int, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append((record.levelno, record.getMessage()))

    def at(self, level: int) -> list[str]:
        """Return the texts logged at ``level``."""
        return [text for lvl, text in self.lines if lvl == level]


def collecting_logger(tag: str) -> tuple[logging.Logger, Lines]:
    """Return a fresh stdlib logger (DEBUG, not propagated) and what it collects."""
    logger = logging.getLogger(f'{tag}.{id(object())}')
    logger.propagate = False
    logger.setLevel(logging.DEBUG)
    lines = Lines()
    logger.addHandler(lines)
    return logger, lines
