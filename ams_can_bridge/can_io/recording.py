"""
The raw recording of one bus (``can.record``): every frame in and out, in a python-can log.

A recording must never cost the bus: a write that fails (disk full) ends the recording with
one error line and the frames keep flowing; a close that fails is logged, not raised, so a
shutdown never turns into a traceback. Thread-safe: the receive thread and senders write.

A crash or a power cut loses at most the last ``FLUSH_PERIOD``: a thread of the recording
hands what python-can's writer buffers to the file (a .blf's buffered container too, its
header then updated to the objects written) and syncs the file to the disk, once a period
while frames come. Without it a killed bridge lost its last buffer (15 frames of a .log,
hundreds of a .blf, still there seconds after they arrived).
"""
from __future__ import annotations

import logging
import os
import threading
from typing import Any

import can

from ams_can_bridge.errors import ConfigError

FLUSH_PERIOD = 1.0  # s: the most a crash or power cut loses of a recording


class Recording:
    """One open python-can log file (its format from the suffix), closed once."""

    def __init__(self, path: str, log: logging.Logger) -> None:
        """Open the file; ConfigError (naming can.record) when python-can cannot write there."""
        try:
            self._writer: can.Listener | None = can.Logger(path)
        except Exception as exc:
            raise ConfigError(f'can.record = {path!r}: cannot record there: {exc}') from exc
        self.path = path
        self._log = log
        self._lock = threading.Lock()
        self._dirty = False  # frames written since the last flush
        self._closed = threading.Event()
        self._flusher = threading.Thread(target=self._flush_every_period, daemon=True,
                                         name='can-record-flush')
        self._flusher.start()

    def write(self, msg: can.Message) -> None:
        """Write one frame (nothing once the recording ended)."""
        # One bus, one recording: the driver's channel object (a name, a path, a number)
        # means nothing in the file, and BLF cannot even store a name with big digits.
        msg.channel = None
        with self._lock:
            writer = self._writer
            if writer is None:
                return
            try:
                writer.on_message_received(msg)
            except Exception as exc:  # disk full: stop recording, keep the bus alive
                self._fail(writer, exc)
            else:
                self._dirty = True

    def _fail(self, writer: Any, exc: Exception) -> None:
        """End the recording after a failed write or flush (under the lock)."""
        self._writer = None
        self._log.error('CAN recording to %s stopped: %s', self.path, exc)
        try:
            writer.stop()  # keep what was written readable
        except Exception:  # the disk that failed may fail again: nothing to add
            pass

    def flush(self) -> None:
        """Hand everything written so far to the disk (what close() would keep)."""
        with self._lock:
            writer = self._writer
            if writer is None or not self._dirty:
                return
            self._dirty = False
            try:
                fileno = _flush(writer)
            except Exception as exc:  # the disk is full or gone: as a failed write
                self._fail(writer, exc)
                return
        if fileno is not None:
            try:  # outside the lock: the receive thread goes on writing meanwhile
                os.fsync(fileno)
            except OSError:  # a closed file (closed meanwhile), a pipe: nothing to sync
                pass

    def _flush_every_period(self) -> None:
        while not self._closed.wait(FLUSH_PERIOD):
            self.flush()

    def close(self) -> None:
        """Flush and close the file (idempotent); a failure is logged, not raised."""
        self._closed.set()
        if self._flusher is not threading.current_thread():
            self._flusher.join(timeout=5.0)
        with self._lock:
            writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.stop()
            except Exception as exc:  # a full disk must not turn shutdown into a traceback
                self._log.error('CAN recording %s not closed cleanly: %s', self.path, exc)


def _flush(writer: Any) -> int | None:
    """
    Write what a python-can writer buffers to its file; return the file's descriptor.

    A BLF writer keeps up to 128 kB of objects for its next compressed container: that
    container is written now, and the header (file size, object count, last time) updated,
    so a file cut here is a complete BLF. python-can 4.4..4.6 name these ``_flush`` and
    ``_write_header``; without them, only the file object is flushed.
    """
    stream = getattr(writer, 'file', None)
    if stream is None or getattr(stream, 'closed', True):
        return None
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
    try:
        return int(stream.fileno())
    except (OSError, ValueError, AttributeError):  # an in-memory or wrapped stream
        return None
