# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
r"""
A fake USB-CAN adapter speaking slcan (Lawicel ASCII) on a pty, for cross-process tests.

The program under test opens ``peer.channel`` (a stable symlink when one was given, else the
pty slave path) with python-can's ``slcan`` interface; pass the option
``sleep_after_open=0`` so python-can does not wait 2 s for a real adapter to boot.

    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN0')
    ... start the bus user on channel str(peer.channel) ...
    peer.wait_open()                       # the user sent 'O'
    peer.send(Frame(0x100, b'\x01'))       # towards the bus user
    peer.wait_received(1)                  # frames the user transmitted
    peer.close()                           # unplug (the symlink disappears too)
    peer.reopen()                          # plug back in (new pty, symlink re-pointed)
    peer.shutdown()

Commands answered as a CANable/Lawicel adapter does (python-can 4.6 sends C, O, L, Sn,
sxxyy, Yn, V, N): '\r' for OK, 'V1013\r' / 'NA123\r' for version / serial number,
'F00\r' for status flags, 'z\r' / 'Z\r' after each transmitted frame, BEL for anything
unknown. Frames are only delivered while the channel is open ('O' or 'L'), like hardware.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path
import pty
import select
import threading
import time
import tty

from ams_can_bridge.protocols.common import Frame

OK = b'\r'
ERROR = b'\a'


def frame_to_slcan(frame: Frame) -> bytes:
    """Encode a classic data frame as an slcan 't' / 'T' line."""
    data = bytes(frame.data)
    if frame.is_extended_id:
        head = f'T{frame.arbitration_id:08X}{len(data):d}'
    else:
        head = f't{frame.arbitration_id:03X}{len(data):d}'
    return (head + data.hex().upper()).encode() + OK


def slcan_to_frame(line: str) -> Frame | None:
    """Decode an slcan 't' / 'T' line (without the CR); None for anything else."""
    try:
        if line[:1] == 't':
            dlc = int(line[4])
            return Frame(int(line[1:4], 16), bytes.fromhex(line[5:5 + 2 * dlc]), False)
        if line[:1] == 'T':
            dlc = int(line[9])
            return Frame(int(line[1:9], 16), bytes.fromhex(line[10:10 + 2 * dlc]), True)
    except (ValueError, IndexError):
        return None
    return None


class SlcanPeer:
    """The adapter side of an slcan serial link: a pty master plus a reader thread."""

    def __init__(self, symlink: str | os.PathLike | None = None,
                 plugged: bool = True) -> None:
        """Create the adapter; with ``plugged=False`` nothing exists until reopen()."""
        self.symlink = Path(symlink) if symlink is not None else None
        self.device_path = ''
        self.commands: list[str] = []
        self.is_open = False
        self.bitrate_command = ''
        self.dropped = 0
        self._received: list[Frame] = []
        self._cond = threading.Condition()
        self._write_lock = threading.Lock()
        self._master = -1
        self._slave = -1
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        if plugged:
            self.reopen()

    @property
    def channel(self) -> str:
        """Return what the bus user opens: the stable symlink, else the pty slave path."""
        return str(self.symlink) if self.symlink is not None else self.device_path

    @property
    def plugged(self) -> bool:
        """Tell whether the adapter currently exists."""
        return self._master >= 0

    # ----------------------------------------------------------------- plug / unplug
    def reopen(self) -> None:
        """Plug the adapter (back) in: a new pty, the symlink re-pointed to it."""
        self.close()
        master, slave = pty.openpty()
        # Raw from the start: no echo or CR translation before the user configures it.
        tty.setraw(slave)
        self._master, self._slave = master, slave
        self.device_path = os.ttyname(slave)
        self.is_open = False
        if self.symlink is not None:
            tmp = self.symlink.with_name(self.symlink.name + '.new')
            if tmp.is_symlink() or tmp.exists():
                tmp.unlink()
            os.symlink(self.device_path, tmp)
            os.replace(tmp, self.symlink)  # atomic: the user never sees a half state
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read_loop, args=(master, self._stop),
                                        name='slcan-peer', daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Unplug: close the pty (the user's reads fail) and remove the symlink."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._thread = None
        for fd in (self._master, self._slave):
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = -1
        self.is_open = False
        if self.symlink is not None and self.symlink.is_symlink():
            self.symlink.unlink()

    def shutdown(self) -> None:
        """Close everything (alias of close, for symmetry with buses)."""
        self.close()

    def __enter__(self) -> 'SlcanPeer':
        """Use as a context manager."""
        return self

    def __exit__(self, *exc: object) -> None:
        """Close on leaving the with block."""
        self.close()

    # --------------------------------------------------------------------- traffic
    def send(self, frame: Frame) -> bool:
        """Deliver a frame to the bus user; False (dropped) while closed or not read."""
        if not self.is_open or self._master < 0:
            self.dropped += 1
            return False
        return self._write(frame_to_slcan(frame))

    def send_raw(self, line: bytes) -> bool:
        """Write raw bytes to the bus user (garbled lines, line noise)."""
        return self.is_open and self._write(line)

    def send_remote(self, arbitration_id: int, dlc: int, extended: bool = False) -> bool:
        """Deliver a remote frame ('r' / 'R' line) to the bus user."""
        if not self.is_open or self._master < 0:
            self.dropped += 1
            return False
        head = f'R{arbitration_id:08X}' if extended else f'r{arbitration_id:03X}'
        return self._write(f'{head}{dlc:d}'.encode() + OK)

    def received(self, clear: bool = False) -> list[Frame]:
        """Return the frames the user transmitted so far (optionally forgetting them)."""
        with self._cond:
            frames = list(self._received)
            if clear:
                self._received.clear()
        return frames

    def wait_received(self, count: int, timeout: float = 5.0) -> list[Frame]:
        """Wait until at least count frames were transmitted by the user; return them all."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while len(self._received) < count:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f'slcan peer: {len(self._received)} of {count} '
                                       f'frames received within {timeout} s')
                self._cond.wait(left)
            return list(self._received)

    def wait_open(self, timeout: float = 5.0) -> None:
        """Wait until the user opened the CAN channel ('O' or 'L')."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not self.is_open:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f'slcan peer: channel not opened within {timeout} s '
                                       f'(commands seen: {self.commands})')
                self._cond.wait(left)

    # -------------------------------------------------------------------- internals
    def _write(self, data: bytes) -> bool:
        master = self._master
        if master < 0:
            return False
        with self._write_lock:
            try:
                # Never block the test forever when the user stopped reading.
                _, writable, _ = select.select([], [master], [], 1.0)
                if not writable:
                    self.dropped += 1
                    return False
                os.write(master, data)
            except OSError:
                self.dropped += 1
                return False
        return True

    def _read_loop(self, master: int, stop: threading.Event) -> None:
        buffer = b''
        while not stop.is_set():
            try:
                readable, _, _ = select.select([master], [], [], 0.05)
                if not readable:
                    continue
                chunk = os.read(master, 4096)
            except OSError as exc:
                if exc.errno in (errno.EIO, errno.EBADF) and not stop.is_set():
                    time.sleep(0.01)  # no slave open right now; wait for one
                    continue
                return
            if not chunk:
                continue
            buffer += chunk
            while True:
                cut = min((i for i in (buffer.find(b'\r'), buffer.find(b'\n')) if i >= 0),
                          default=-1)
                if cut < 0:
                    break
                line, buffer = buffer[:cut], buffer[cut + 1:]
                if line:
                    self._command(line.decode('ascii', 'replace'))

    def _command(self, line: str) -> None:
        kind = line[0]
        reply = OK
        with self._cond:
            if kind in 'tTrRdDbB':
                frame = slcan_to_frame(line)
                if frame is None and kind in 'tT':
                    reply = ERROR
                elif frame is not None:
                    self._received.append(frame)
                else:
                    self.commands.append(line)
                if reply == OK:
                    reply = (b'Z' if kind in 'TRDB' else b'z') + OK
            else:
                self.commands.append(line)
                if kind in 'OL':
                    self.is_open = True
                elif kind == 'C':
                    self.is_open = False
                elif kind in 'SsY':
                    self.bitrate_command = line
                elif kind == 'V':
                    reply = b'V1013' + OK
                elif kind == 'N':
                    reply = b'NA123' + OK
                elif kind == 'F':
                    reply = b'F00' + OK
                elif kind not in 'ZMmXWQU':
                    reply = ERROR
            self._cond.notify_all()
        self._write(reply)
