"""Replay of a recorded CAN log as if it were a bus (the 'replay' interface)."""
from __future__ import annotations

import os
import time
from typing import Iterator

import can

from ams_can_bridge.errors import ConfigError, LogFileError


def open_log(path: str) -> can.io.generic.MessageReader:
    """
    Open a log with python-can's reader for its suffix, timestamps as the log has them.

    An .asc file counts its times from the "date" line of its header: read them absolute
    (python-can's ASCReader defaults to times relative to the start), so that every format
    gives the moment the frame was on the bus.
    """
    if path.lower().endswith('.asc'):
        return can.LogReader(path, relative_timestamp=False)
    return can.LogReader(path)


class ReplayBus:
    """
    Plays a log file that can.LogReader reads, keeping its timing scaled by ``rate``.

    Duck-types the part of can.BusABC the receive loop uses: ``recv(timeout)`` returns the
    next message once it is due (None while waiting), ``send`` accepts and discards (there
    is no bus behind a recording), ``shutdown`` closes the file. ``finished`` turns True
    after the last message; ``played`` counts the messages handed out.
    """

    def __init__(self, path: str, rate: float = 1.0) -> None:
        if not path:
            raise ConfigError('replay: can.channel must name the log file to play')
        if not os.path.isfile(path):
            raise LogFileError(f'replay: log file {path!r} does not exist')
        if not os.access(path, os.R_OK):
            raise LogFileError(f'replay: log file {path!r} is not readable')
        self.path = path
        self.rate = rate
        # LogReader picks the format from the extension and raises ValueError for others.
        self._reader = open_log(path)
        self._messages: Iterator[can.Message] = iter(self._reader)
        self._pending: can.Message | None = None
        self._log_start: float | None = None
        self._wall_start = 0.0
        self._last_due = 0.0
        self.played = 0
        self.finished = False
        self.error = ''
        self.channel_info = f'replay of {path}'

    def _due(self, msg: can.Message) -> float:
        """Monotonic time at which msg is to be handed out."""
        if self._log_start is None:
            self._log_start = msg.timestamp
            self._wall_start = time.monotonic()
        due = self._wall_start + (msg.timestamp - self._log_start) / self.rate
        # Concatenated logs may step back in time: never wait for the past, keep order.
        self._last_due = max(due, self._last_due)
        return self._last_due

    def recv(self, timeout: float | None = None) -> can.Message | None:
        """Return the next message when its time has come, or None after timeout."""
        if self._pending is None:
            if self.finished:
                if timeout:
                    time.sleep(timeout)
                return None
            try:
                self._pending = next(self._messages)
            except StopIteration:
                self.finished = True
                return None
            except Exception as exc:  # a corrupt line: stop here rather than loop forever
                self.error = f'{type(exc).__name__}: {exc}'
                self.finished = True
                return None
            self._pending_due = self._due(self._pending) if self.rate > 0 else 0.0
        if self.rate > 0:
            wait = self._pending_due - time.monotonic()
            if wait > 0:
                if timeout is not None and wait > timeout:
                    time.sleep(timeout)
                    return None
                time.sleep(wait)
        msg, self._pending = self._pending, None
        self.played += 1
        return msg

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Accept and discard: a recording has nobody to send to (frames are recorded)."""

    def shutdown(self) -> None:
        """Close the log file."""
        stop = getattr(self._reader, 'stop', None)
        if stop is not None:
            stop()
