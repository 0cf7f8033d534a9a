"""
python-can's slcan bus, reading the serial port in blocks instead of one byte per call.

python-can 4.6's ``slcanBus._read`` calls ``serial.read(1)`` for every byte of a line: a
frame of 27 characters costs about 54 system calls (pyserial selects, then reads) and as
many trips through Python. That was ~200 us per frame on this machine and most of the
bridge's CPU at full load. ``BulkReadSlcanBus`` takes everything the port has ready in one
``read`` and hands the lines out of its buffer; what the adapter sends, how a line is
parsed, opening, writing, flushing and closing stay python-can's own code.

Used for ``can.interface: slcan`` unless ``can.slcan_bulk_read`` is false.
"""
from __future__ import annotations

import logging
import time

import can
from can.exceptions import error_check
from can.interfaces.slcan import slcanBus

# python-can ends a line with CR (OK) or BEL (error); it returns the line with its end.
_CR = 0x0D
_BEL = 0x07
# One read takes at most this much: a full pty/USB buffer is a few kB; lines are <= 150.
_MAX_READ = 4096
_log = logging.getLogger(__name__)


class BulkReadSlcanBus(slcanBus):
    """
    slcanBus whose ``_read`` takes every waiting byte in one system call.

    Same contract as python-can's: return the next line with its CR/BEL end, or None once
    ``timeout`` has passed without a complete line; bytes after the line stay buffered for
    the next call. A read blocks for at most the port's own ``timeout`` (the bridge's 0.5 s
    default), so a stop is seen as quickly as with python-can's reader.
    """

    _bulk = False  # python-can's reader until __init__ has checked (it may read while opening)

    def __init__(self, *args: object, **kwargs: object) -> None:
        """Open as python-can does; check that its reader keeps what this one relies on."""
        super().__init__(*args, **kwargs)
        # python-can's own line buffer and pyserial port: if a python-can release renames
        # them, fall back to its reader rather than fail (setup.py allows python-can >= 4.4).
        self._bulk = (isinstance(getattr(self, '_buffer', None), bytearray)
                      and hasattr(getattr(self, 'serialPortOrig', None), 'in_waiting'))
        if not self._bulk:
            _log.warning("slcan: python-can's slcanBus internals changed; reading with "
                         "python-can's own byte-per-call reader")

    def _read(self, timeout: float | None) -> str | None:
        if not self._bulk:
            return super()._read(timeout)
        buffer = self._buffer
        line = self._next_line(buffer)
        if line is not None:
            return line
        port = self.serialPortOrig
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            # in_waiting is one ioctl; read(n) of what is there returns at once, and read(1)
            # on an empty port waits for the first byte (up to the port's timeout).
            with error_check('Could not read from serial device'):  # as python-can's reader
                chunk = port.read(min(max(1, port.in_waiting), _MAX_READ))
            if chunk:
                buffer.extend(chunk)
                # Outside error_check: a line that is not text is a bad line (ValueError),
                # not a failed port (python-can's reader reports it as CanOperationError).
                line = self._next_line(buffer)
                if line is not None:
                    return line
            if deadline is not None and time.monotonic() >= deadline:
                return None

    @staticmethod
    def _next_line(buffer: bytearray) -> str | None:
        """Take the first CR- or BEL-ended line out of the buffer (None: none complete)."""
        cr = buffer.find(_CR)
        bel = buffer.find(_BEL)
        if cr < 0 and bel < 0:
            return None
        end = bel if cr < 0 or 0 <= bel < cr else cr
        raw = bytes(buffer[:end + 1])
        # Out of the buffer before decoding: line noise that is not text raises once (the
        # caller counts an unreadable line), it must not stay to fail every later call.
        del buffer[:end + 1]
        return raw.decode()


def open_bulk_slcan(channel: str, **kwargs: object) -> BulkReadSlcanBus:
    """Open it as ``can.Bus(interface='slcan', ...)`` would (python-can's config merged)."""
    config = can.util.load_config(config={'interface': 'slcan', 'channel': channel, **kwargs})
    del config['interface']
    return BulkReadSlcanBus(config.pop('channel'), **config)
