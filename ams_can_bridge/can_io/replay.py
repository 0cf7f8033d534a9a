# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Replay of a recorded CAN log as if it were a bus (the 'replay' interface)."""
from __future__ import annotations

import math
import time
from typing import Iterator

import can

from ams_can_bridge.can_io.blf_bounded import BoundedBLFReader
from ams_can_bridge.errors import ConfigError, LogFileError
from ams_can_bridge.input_files import file_problem

# A ROS time holds its seconds in an int32 (builtin_interfaces/Time): 2038-01-19 03:14:08 UTC
# is the first moment it cannot stamp.
STAMP_END = float(2 ** 31)


def stamp_problem(stamp: float) -> str:
    """
    Say why a log timestamp cannot be a frame's moment ('' when it can).

    Not a number, infinite, before 1970 or from 2038-01-19 03:14:08 UTC on (a ROS stamp
    holds int32 seconds): such an entry is a bad log entry, counted and skipped by log2bag
    and by a replay, never stamped with something else (the host clock, a wrapped year).
    """
    if not math.isfinite(stamp):
        return 'not a time'
    if stamp < 0:
        return 'before 1970'
    if stamp >= STAMP_END:
        return 'past 2038-01-19 03:14:07 UTC, the last second a ROS stamp holds'
    return ''


def open_log(path: str) -> can.io.generic.MessageReader:
    """
    Open a log with python-can's reader for its suffix, timestamps as the log has them.

    An .asc file counts its times from the "date" line of its header: read them absolute
    (python-can's ASCReader defaults to times relative to the start), so that every format
    gives the moment the frame was on the bus.
    """
    if path.lower().endswith('.asc'):
        return can.LogReader(path, relative_timestamp=False)
    if path.lower().endswith('.blf'):  # one object bounded (a compressed bomb is refused)
        return BoundedBLFReader(path)
    return can.LogReader(path)


class ReplayBus:
    """
    Plays a log file that can.LogReader reads, keeping its timing scaled by ``rate``.

    Duck-types the part of can.BusABC the receive loop uses: ``recv(timeout)`` returns the
    next message once it is due (None while waiting), ``send`` accepts and discards (there
    is no bus behind a recording), ``shutdown`` closes the file. ``finished`` turns True
    after the last message; ``played`` counts the messages handed out.

    ``log_time()`` is the replay's moment on the log's clock, the devices' clock during a
    replay: the log time of the frame handed out last, from the moment ``recv`` returned it
    until the receive loop asks for the next one (it is being handled: a stalled handling
    changes nothing of what the devices see); in between, that time moved on by the wall
    time since then (times the rate), but never past the next frame still to be handed out
    (a delivery that falls behind the log does not age what the log holds). Before the
    first frame it is the log's first moment; after the last it goes on moving, so the
    devices go stale once the log has ended.
    """

    def __init__(self, path: str, rate: float = 1.0) -> None:
        """Open the log and read its first frame (``log_start``; NaN when there is none)."""
        if not path:
            raise ConfigError('replay: can.channel must name the log file to play')
        problem = file_problem(path)
        if problem:
            raise LogFileError(f'replay: log file {path!r} {problem}')
        self.path = path
        self.rate = rate
        # LogReader picks the format from the extension and raises ValueError for others.
        self._reader = open_log(path)
        self._log_start: float | None = None
        self._wall_start = 0.0
        self._last_due = 0.0
        self.played = 0
        self.finished = False
        self.error = ''
        self.skipped = 0  # entries whose timestamp is no time (stamp_problem)
        self.last_skipped = ''
        self.channel_info = f'replay of {path}'
        self._messages: Iterator[can.Message] = self._timed(iter(self._reader))
        self._pending_due: float | None = None
        self._pending = self._next()  # read ahead: the log's first moment
        self.log_start = math.nan if self._pending is None else self._pending.timestamp
        # the log time between frames advances this much per wall second (as fast as
        # possible: like real time, bounded by the next frame anyway)
        self._pace = rate if rate > 0 else 1.0
        # (log time, monotonic time it started to move (None: a frame is being handled),
        # the next frame's log time (inf: none)): one tuple, so that a reader on another
        # thread never sees half of an update
        self._clock: tuple[float, float | None, float] = (
            self.log_start, time.monotonic(),
            math.inf if self._pending is None else self.log_start)

    def _timed(self, messages: Iterator[can.Message]) -> Iterator[can.Message]:
        """Yield the messages whose timestamp is a time; count the others."""
        for msg in messages:
            problem = stamp_problem(msg.timestamp)
            if problem:
                self.skipped += 1
                self.last_skipped = f'timestamp {msg.timestamp!r}: {problem}'
                continue
            yield msg

    def _next(self) -> can.Message | None:
        """Return the next message with a usable timestamp; None (finished) at the end."""
        try:
            return next(self._messages)
        except StopIteration:
            self.finished = True
        except Exception as exc:  # a corrupt line: stop here rather than loop forever
            self.error = f'{type(exc).__name__}: {exc}'
            self.finished = True
        return None

    def _due(self, msg: can.Message) -> float:
        """Monotonic time at which msg is to be handed out."""
        if self._log_start is None:
            self._log_start = msg.timestamp
            self._wall_start = time.monotonic()
        due = self._wall_start + (msg.timestamp - self._log_start) / self.rate
        # Concatenated logs may step back in time: never wait for the past, keep order.
        self._last_due = max(due, self._last_due)
        return self._last_due

    def log_time(self) -> float:
        """Return the replay's moment on the log's clock (NaN: the log has no frame)."""
        base, since, upcoming = self._clock
        if since is None:  # the frame handed out last is being handled: its moment
            return base
        moved = base + (time.monotonic() - since) * self._pace
        return min(moved, max(upcoming, base))

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """Return the next message when its time has come, or None after timeout."""
        base, since, upcoming = self._clock
        if since is None:  # the receive loop is done with the frame handed out last
            self._clock = (base, time.monotonic(), upcoming)
        if self._pending is None:
            if self.finished:
                if timeout:
                    time.sleep(timeout)
                return None
            self._pending = self._next()
            base, since, _ = self._clock
            if self._pending is None:
                self._clock = (base, since, math.inf)  # the end: the log time runs on
                return None
            self._clock = (base, since, self._pending.timestamp)
        if self._pending_due is None:
            self._pending_due = self._due(self._pending) if self.rate > 0 else 0.0
        if self.rate > 0:
            wait = self._pending_due - time.monotonic()
            if wait > 0:
                if timeout is not None and wait > timeout:
                    time.sleep(timeout)
                    return None
                time.sleep(wait)
        msg, self._pending, self._pending_due = self._pending, None, None
        self.played += 1
        self._clock = (msg.timestamp, None, msg.timestamp)
        return msg

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Accept and discard: a recording has nobody to send to (frames are recorded)."""

    def shutdown(self) -> None:
        """Close the log file."""
        stop = getattr(self._reader, 'stop', None)
        if stop is not None:
            stop()
