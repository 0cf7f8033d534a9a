# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The raw recording of one bus (``can.record``): every frame in and out, in a python-can log.

A recording must never cost the bus: a write that fails (disk full) ends the recording with
one error line and the frames keep flowing; a close that fails is logged, not raised, so a
shutdown never turns into a traceback. Thread-safe: the receive thread and senders write.

A crash or a power cut loses at most the last ``FLUSH_PERIOD``: what python-can's writer
buffers (a .blf's container too, its header then updated to the objects written) is handed
to the file by the thread that writes a frame once ``FLUSH_EVERY`` has passed, or by
``tick()``, which the receive thread calls while the bus is quiet; a thread of the recording
then syncs the file to the disk (``fsync``, without the lock: a slow disk never holds up a
frame). Without it a killed bridge lost its last buffer (15 frames of a .log, hundreds of a
.blf, still there seconds after they arrived).
"""
from __future__ import annotations

import logging
import os
import threading
import time
from typing import Any

import can

from ams_can_bridge.errors import ConfigError

FLUSH_PERIOD = 1.0  # s: the most a crash or power cut loses of a recording
# s after a flush the next is due: room within FLUSH_PERIOD for the receive thread's
# quiet wake-ups (every 0.1 s) and the sync after it
FLUSH_EVERY = 0.8


def channel_name(interface: str, channel: str) -> str:
    """
    Return the bus's name in a candump .log: 'can0' as is, a serial port by its device name.

    A log names its interface by one word (candump, canplayer and python-can split the line
    on blanks): '/dev/ttyACM0' becomes 'ttyACM0', a replayed log is 'replay'.
    """
    if interface == 'replay':
        return 'replay'
    name = '_'.join(channel.rstrip('/').rsplit('/', 1)[-1].split())
    return name or interface


class Recording:
    """One open python-can log file (its format from the suffix), closed once."""

    def __init__(self, path: str, log: logging.Logger, channel: str = '') -> None:
        """
        Open the file; ConfigError (naming can.record) when python-can cannot write there.

        ``channel`` names the bus in a candump .log (python-can writes 'vcan0' otherwise):
        ``channel_name`` of the bus's can.channel.
        """
        try:
            self._writer: can.Listener | None = can.Logger(path)
        except Exception as exc:
            raise ConfigError(f'can.record = {path!r}: cannot record there: {exc}') from exc
        if channel and isinstance(self._writer, can.CanutilsLogWriter):
            self._writer.channel = channel  # the formats with numbered channels keep theirs
        self.path = path
        self._log = log
        self._lock = threading.Lock()
        self._dirty = False  # frames written since the last flush
        self._flushed_at = time.monotonic()
        self._fd = _fileno(self._writer)  # what the sync thread syncs (None: nothing)
        self._unsynced = threading.Event()  # flushed to the file, not yet to the disk
        self._closed = threading.Event()
        self._syncer = threading.Thread(target=self._sync, daemon=True, name='can-record-sync')
        self._syncer.start()

    def write(self, msg: can.Message) -> None:
        """Write one frame (nothing once the recording ended); flush when one is due."""
        # One bus, one recording: the driver's channel object (a name, a path, a number)
        # means nothing in the file, and BLF cannot even store a name with big digits.
        msg.channel = None
        with self._lock:
            writer = self._writer
            if writer is None:
                return
            try:
                writer.on_message_received(msg)
                self._dirty = True
                if time.monotonic() - self._flushed_at >= FLUSH_EVERY:
                    self._flush(writer)
            except Exception as exc:  # disk full: stop recording, keep the bus alive
                self._fail(writer, exc)

    def tick(self) -> None:
        """Flush what waits once it is due (the receive thread calls it while quiet)."""
        if self._dirty and time.monotonic() - self._flushed_at >= FLUSH_EVERY:
            self.flush()

    def flush(self) -> None:
        """Hand everything written so far to the file, and to the disk soon after."""
        with self._lock:
            writer = self._writer
            if writer is None or not self._dirty:
                return
            try:
                self._flush(writer)
            except Exception as exc:  # the disk is full or gone: as a failed write
                self._fail(writer, exc)

    def _flush(self, writer: Any) -> None:
        """Flush the writer (under the lock); the sync thread syncs it to the disk."""
        _flush(writer)
        self._dirty = False
        self._flushed_at = time.monotonic()
        self._unsynced.set()

    def _fail(self, writer: Any, exc: Exception) -> None:
        """End the recording after a failed write or flush (under the lock)."""
        self._writer = None
        self._fd = None
        self._log.error('CAN recording to %s stopped: %s', self.path, exc)
        try:
            writer.stop()  # keep what was written readable
        except Exception:  # the disk that failed may fail again: nothing to add
            pass

    def _sync(self) -> None:
        while not self._closed.is_set():
            if not self._unsynced.wait(FLUSH_PERIOD):
                continue
            self._unsynced.clear()
            fd = self._fd
            if fd is not None:
                try:
                    os.fsync(fd)
                except OSError:  # closed meanwhile, or a file that cannot sync (a pipe)
                    pass

    def close(self) -> None:
        """Flush and close the file (idempotent); a failure is logged, not raised."""
        self._closed.set()
        self._unsynced.set()  # wakes the sync thread: it sees closed and ends
        if self._syncer is not threading.current_thread():
            self._syncer.join(timeout=5.0)
        with self._lock:
            writer, self._writer, self._fd = self._writer, None, None
        if writer is not None:
            try:
                writer.stop()
            except Exception as exc:  # a full disk must not turn shutdown into a traceback
                self._log.error('CAN recording %s not closed cleanly: %s', self.path, exc)


def _flush(writer: Any) -> None:
    """
    Write what a python-can writer buffers to its file.

    A BLF writer keeps up to 128 kB of objects for its next compressed container: that
    container is written now, and the header (file size, object count, last time) updated,
    so a file cut here is a complete BLF. python-can 4.4..4.6 name these ``_flush`` and
    ``_write_header``; without them, only the file object is flushed.
    """
    stream = getattr(writer, 'file', None)
    if stream is None or getattr(stream, 'closed', True):
        return
    container = getattr(writer, '_flush', None)
    header = getattr(writer, '_write_header', None)
    if isinstance(writer, can.BLFWriter) and callable(container) and callable(header):
        container()
        if stream.seekable():
            end = stream.tell()
            stream.seek(0)
            header(end)
            stream.seek(end)
    stream.flush()


def _fileno(writer: Any) -> int | None:
    """Return the descriptor of a writer's file (None: an in-memory or wrapped stream)."""
    try:
        return int(writer.file.fileno())
    except (OSError, ValueError, AttributeError):
        return None
