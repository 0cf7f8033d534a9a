"""
The raw recording of one bus (``can.record``): every frame in and out, in a python-can log.

A recording must never cost the bus: a write that fails (disk full) ends the recording with
one error line and the frames keep flowing; a close that fails is logged, not raised, so a
shutdown never turns into a traceback. Thread-safe: the receive thread and senders write.
"""
from __future__ import annotations

import logging
import threading

import can

from ams_can_bridge.errors import ConfigError


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
                self._writer = None
                self._log.error('CAN recording to %s stopped: %s', self.path, exc)
                try:
                    writer.stop()  # keep what was written readable
                except Exception:  # the disk that failed may fail again: nothing to add
                    pass

    def close(self) -> None:
        """Flush and close the file (idempotent); a failure is logged, not raised."""
        with self._lock:
            writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.stop()
            except Exception as exc:  # a full disk must not turn shutdown into a traceback
                self._log.error('CAN recording %s not closed cleanly: %s', self.path, exc)
