# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
python-can's slcan bus, reading the serial port in blocks instead of one byte per call.

python-can 4.6's ``slcanBus._read`` calls ``serial.read(1)`` for every byte of a line: a
frame of 27 characters costs about 54 system calls (pyserial selects, then reads) and as
many trips through Python, most of the bridge's CPU at full load (bench/README.md).
``BulkReadSlcanBus`` takes everything the port has ready in one ``read`` and hands the
lines out of its buffer; what the adapter sends, how a line is
parsed, opening, writing, flushing and closing stay python-can's own code.

Used for ``can.interface: slcan``; with ``can.slcan_bulk_read: false`` it reads with
python-can's own reader.

A line is at most ``MAX_LINE`` bytes: an adapter that sends bytes without a line end (line
noise, a wrong baud rate, a broken firmware) has them dropped once they exceed it, counted
in ``garbage_lines`` / ``garbage_bytes`` (the CAN bus status shows them, WARN), instead of a
buffer that grows without limit and is searched again for every byte that arrives.

It also opens the serial port exclusively. Two programs reading one serial adapter each get
part of every line (python-can then reports "multiple access on port?" and both lose the bus
every few seconds). Before python-can touches the port, the bus takes an exclusive ``flock``
on it, the lock pyserial's ``exclusive=True`` takes: a second bridge (or any program that
opens the port with pyserial's ``exclusive=True``) fails before it has written or read a
byte, with a message that says to share the bus through SocketCAN (slcand) instead.
"""
from __future__ import annotations

import errno
import logging
import os
import threading
import time

import can
from can.exceptions import CanInitializationError, error_check
from can.interfaces.slcan import slcanBus

# python-can ends a line with CR (OK) or BEL (error); it returns the line with its end.
_CR = 0x0D
_BEL = 0x07
# One read takes at most this much: a full pty/USB buffer is a few kB; lines are <= 150.
_MAX_READ = 4096
# No slcan line is longer: a CAN FD frame with 64 bytes and a timestamp ('B', 8 ID digits,
# DLC, 128 data digits, 4 timestamp digits, CR) is 143 characters.
MAX_LINE = 200
_log = logging.getLogger(__name__)
# python-can's default wait after opening the port (an adapter that resets on open boots)
SLEEP_AFTER_SERIAL_OPEN = float(getattr(slcanBus, '_SLEEP_AFTER_SERIAL_OPEN', 2.0))  # s

try:  # POSIX; on Windows a COM port is exclusive to one program anyway
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None  # type: ignore[assignment]


def _lock_holders(path: str) -> list[int]:
    """Return the PIDs /proc/locks names for an flock on path (best effort, Linux)."""
    try:
        st = os.stat(path)
        with open('/proc/locks', encoding='ascii') as stream:
            lines = stream.read().splitlines()
    except OSError:
        return []
    dev = f'{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}'
    pids = []
    for line in lines:
        parts = line.split()
        # '1: FLOCK  ADVISORY  WRITE 1234 00:05:17 0 EOF' (blocked waiters have a '->')
        if len(parts) >= 6 and parts[1] == 'FLOCK' and parts[5] == dev \
                and parts[4].isdigit():
            pids.append(int(parts[4]))
    return pids


def port_in_use_message(port: str, holders: list[int] | None = None) -> str:
    """Say that the serial port is taken, by whom if known, and how to share a bus."""
    who = (f' by process {", ".join(str(p) for p in holders)}' if holders
           else ' by another program')
    return (f'serial port {port} is in use{who} (another bridge?): a serial CAN adapter '
            'serves one program at a time. To share one bus between several programs, '
            f'attach the adapter to SocketCAN (sudo slcand -o -s6 {port} can0 && sudo ip '
            'link set can0 up) and give every program can.interface: socketcan, '
            'can.channel: can0')


def lock_serial_port(channel: str) -> int | None:
    """
    Take an exclusive flock on a serial port path: the fd that holds it, or None.

    None when there is nothing to lock (a pyserial URL such as socket://, no fcntl, a port
    that does not open: python-can then reports that itself). Raises
    CanInitializationError naming the port, and what to do, when another program holds it.
    """
    port = channel.split('@', 1)[0]  # python-can's '<port>@<tty baud rate>'
    if fcntl is None or not port or '://' in port:
        return None
    try:
        # No tcsetattr, no flush, no DTR change: opening alone does not disturb a user.
        fd = os.open(port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        taken = exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES)
    else:
        return fd
    if not taken:
        return None  # a file system without flock: nothing to enforce
    # raised outside the except block: the message is the whole reason (no errno appended)
    raise CanInitializationError(port_in_use_message(port, _lock_holders(port)))


class BulkReadSlcanBus(slcanBus):
    """
    slcanBus whose ``_read`` takes every waiting byte in one system call.

    Same contract as python-can's: return the next line with its CR/BEL end, or None once
    ``timeout`` has passed without a complete line; bytes after the line stay buffered for
    the next call. A read blocks for at most the port's own ``timeout`` (the bridge's 0.5 s
    default), so a stop is seen as quickly as with python-can's reader.
    """

    _bulk = False  # python-can's reader until __init__ has checked (it may read while opening)
    _lock_fd: int | None = None
    garbage_lines = 0  # runs of bytes longer than MAX_LINE without a line end, dropped
    garbage_bytes = 0

    _settle_for = 0.0  # s still to wait after the port opened, before the first command
    _stop: threading.Event | None = None

    def __init__(self, channel: str, *args: object, bulk_read: bool = True,
                 stop: threading.Event | None = None, **kwargs: object) -> None:
        """
        Lock the port, then open as python-can does; check what the block reader relies on.

        Raises CanInitializationError, before python-can has touched the port, when another
        program holds it (``lock_serial_port``). ``bulk_read`` False keeps python-can's reader.
        python-can sleeps ``sleep_after_open`` (2 s) after opening the port, where Ctrl-C
        waited it out: here that wait is on ``stop``, before the first command, and a stop
        during it ends the open at once (CanInitializationError, the port closed).
        """
        self._lock_fd = lock_serial_port(str(channel))
        self._stop = stop
        settle = kwargs.pop('sleep_after_open', SLEEP_AFTER_SERIAL_OPEN)
        self._settle_for = float(settle) if isinstance(settle, (int, float, str)) else 0.0
        kwargs['sleep_after_open'] = 0
        try:
            super().__init__(channel, *args, **kwargs)  # type: ignore[arg-type]  # passed on
        except BaseException:
            port = getattr(self, 'serialPortOrig', None)
            if port is not None:
                port.close()
            self._unlock()
            raise
        # python-can's own line buffer and pyserial port: if a python-can release renames
        # them, fall back to its reader rather than fail (setup.py allows python-can >= 4.4).
        self._bulk = bulk_read and (
            isinstance(getattr(self, '_buffer', None), bytearray)
            and hasattr(getattr(self, 'serialPortOrig', None), 'in_waiting'))
        if bulk_read and not self._bulk:
            _log.warning("slcan: python-can's slcanBus internals changed; reading with "
                         "python-can's own byte-per-call reader")

    def _settle(self) -> None:
        """Wait what python-can would have slept after opening, unless a stop comes first."""
        wait, self._settle_for = self._settle_for, 0.0
        if wait <= 0:
            return
        if self._stop is None:
            time.sleep(wait)
        elif self._stop.wait(wait):
            raise CanInitializationError('stopped while the adapter settled after opening')

    def set_bitrate(self, bitrate: int, data_bitrate: int | None = None) -> None:
        """Set the bit rate as python-can does, after the settling wait."""
        self._settle()
        super().set_bitrate(bitrate, data_bitrate)

    def set_bitrate_reg(self, btr: str) -> None:
        """Set the bit timing register as python-can does, after the settling wait."""
        self._settle()
        super().set_bitrate_reg(btr)

    def open(self) -> None:
        """Open the CAN channel as python-can does, after the settling wait."""
        self._settle()
        super().open()

    def shutdown(self) -> None:
        """Close as python-can does, then release the port's lock."""
        try:
            super().shutdown()
        finally:
            self._unlock()

    def _unlock(self) -> None:
        fd, self._lock_fd = self._lock_fd, None
        if fd is not None:
            os.close(fd)  # closing the fd releases the flock

    def _read(self, timeout: float | None) -> str | None:
        if not self._bulk:  # python-can's reader: its buffer bounded between calls
            line = super()._read(timeout)
            if line is not None and len(line) > MAX_LINE:
                self._garbage(len(line))
                return None
            if len(self._buffer) > MAX_LINE:
                self._garbage(len(self._buffer))
                self._buffer.clear()
            return line
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
                if len(buffer) > MAX_LINE:  # no line end in sight: not a line, drop it
                    self._garbage(len(buffer))
                    buffer.clear()
            if deadline is not None and time.monotonic() >= deadline:
                return None

    def _garbage(self, size: int) -> None:
        self.garbage_lines += 1
        self.garbage_bytes += size

    def _next_line(self, buffer: bytearray) -> str | None:
        """Take the first CR- or BEL-ended line out of the buffer (None: none complete)."""
        while True:
            cr = buffer.find(_CR)
            bel = buffer.find(_BEL)
            if cr < 0 and bel < 0:
                return None
            end = bel if cr < 0 or 0 <= bel < cr else cr
            raw = bytes(buffer[:end + 1])
            # Out of the buffer before decoding: line noise that is not text raises once
            # (the caller counts an unreadable line), it must not stay to fail every call.
            del buffer[:end + 1]
            if len(raw) <= MAX_LINE:
                return raw.decode()
            self._garbage(len(raw))  # the end of a run of garbage: no line either


def open_bulk_slcan(channel: str, bulk_read: bool = True, stop: threading.Event | None = None,
                    **kwargs: object) -> BulkReadSlcanBus:
    """
    Open it as ``can.Bus(interface='slcan', ...)`` would (python-can's config merged).

    ``stop``: set, it ends the wait after opening the port (see ``BulkReadSlcanBus``).
    """
    config = can.util.load_config(config={'interface': 'slcan', 'channel': channel, **kwargs})
    del config['interface']
    return BulkReadSlcanBus(config.pop('channel'), bulk_read=bulk_read, stop=stop, **config)
