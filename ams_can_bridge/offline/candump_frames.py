# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's own reader of candump ``.log`` files: python-can's frames, without a can.Message each.

python-can's ``CanutilsLogReader`` costs about 5 us a line, most of it building a
``can.Message`` and parsing the data byte by byte. This reader takes the file in chunks of
``CHUNK`` characters and parses a chunk's lines all at once, in C (``str.split``, ``map``
over ``float``/``bytes.fromhex``, ``zip``), when every line of it is a common one::

    (1790000000.000000) can0 311#0102030405060708
    (1790000000.000000) vcan0 18FF50E5#01 R

a timestamp in parentheses, a channel, an ID, one ``#``, up to 8 data bytes in hex, with or
without python-can's direction (`` R``/`` T``), single spaces, ASCII, the ID below the
error/extended flags, a timestamp a ROS stamp holds. The values are python-can's own: the
same functions on the same pieces of the line (``float`` of what is between the
parentheses, ``int(id, 16)``, an extended ID when it has more than 3 digits). A chunk with a
line that is not common (CAN FD ``##``, remote ``#R``, an error frame, odd spacing, a bad
stamp, a garbled line) is halved until the halves parse; the lines of a part of at most
``LINES_ALONE`` lines that does not go to python-can's reader one by one, with its errors
and checks counted as ``LogFrames`` counts them (``LogFrames.accepted``), so every frame,
value and counter is python-can's.
"""
from __future__ import annotations

import io
from itertools import repeat
from typing import Iterator, List, Optional, TextIO

import can

from ams_can_bridge.can_io.replay import STAMP_END
from ams_can_bridge.offline.frame_tuples import Counts, Frame, message_frame

CHUNK = 1 << 16  # characters read at once (about 1,300 lines)
LINES_ALONE = 32  # a part of this many lines that does not parse goes line by line
IDS_KEPT = 4096  # IDs parsed and kept (a log has a few hundred; a crafted one is bounded)
# The ASCII whitespace other than ' ' and '\n' (str.split splits on it; a common line has none)
_OTHER_SPACE = '\t\x0b\x0c\r\x1c\x1d\x1e\x1f'
_DIRECTIONS = frozenset('RTrt')
_FLAGS = 0x20000000  # python-can masks an ID from here (CAN_ERR_FLAG and up)


class CandumpFrames:
    """The frames of a candump ``.log`` text file as ``Frame`` tuples, python-can's values."""

    def __init__(self, counts: Counts, file: TextIO) -> None:
        """Read ``file`` (opened as python-can opens it: text, universal newlines)."""
        self.counts = counts
        self.file = file
        self.lines_read = 0  # complete lines handed on (where python-can takes over)
        self._ids: dict[str, int] = {}

    def chunks(self) -> Iterator[List[Frame]]:
        """
        Yield the frames, a list a chunk.

        ``counts.cut_line`` is set to a last line without an end (not read).

        A chunk that is not text in the file's encoding raises UnicodeDecodeError:
        ``lines_read`` says how many lines were read before it.
        """
        read = self.file.read
        rest = ''
        while True:
            chunk = read(CHUNK)
            if not chunk:
                break
            text = rest + chunk if rest else chunk
            cut = text.rfind('\n') + 1
            if not cut:
                rest = text
                continue
            rest = text[cut:]
            body = text[:cut]
            lines = body.count('\n')
            got = self._block(body, lines)
            if got is None:
                got = []
                self._parts(body[:-1].split('\n'), got)
            self.lines_read += lines
            yield got
        if rest:
            self.counts.cut_line = rest

    def _parts(self, lines: List[str], out: List[Frame]) -> None:
        """Parse lines that do not parse all at once: halves, then line by line."""
        if len(lines) <= LINES_ALONE:
            for line in lines:
                self._python_can(line, out)
            return
        middle = len(lines) // 2
        for part in (lines[:middle], lines[middle:]):
            got = self._block('\n'.join(part) + '\n', len(part))
            if got is None:
                self._parts(part, out)
            else:
                out += got

    def _python_can(self, line: str, out: List[Frame]) -> None:
        """Read one line with python-can's reader; count what LogFrames counts."""
        counts = self.counts
        try:
            for msg in can.CanutilsLogReader(io.StringIO(line)):
                if counts.accepted(msg):
                    out.append(message_frame(msg))
        except Exception as exc:  # what LogFrames counts of python-can's reader
            counts.bad += 1
            counts.last_bad = f'{type(exc).__name__}: {exc}'

    def _block(self, text: str, lines: int) -> Optional[List[Frame]]:
        """
        Return the frames of ``lines`` lines (each ending with a newline).

        None when any of them is not a common line.
        """
        if not text.isascii():
            return None
        for char in _OTHER_SPACE:
            if char in text:
                return None
        if text.count('#') != lines:
            return None
        # every '#' and every line end its own token: a common line is [stamp, channel, ID,
        # '#', data, (direction,) '\n'], each in its place, or the block is not common
        tokens = text.replace('#', ' # ').replace('\n', ' \n ').split(' ')
        tokens.pop()  # after the last '\n'
        width = len(tokens) // lines
        if width == 7:
            if not _DIRECTIONS.issuperset(tokens[5::7]):
                return None
        elif width != 6:
            return None
        if len(tokens) != width * lines or tokens[width - 1::width].count('\n') != lines \
                or tokens[3::width].count('#') != lines or not all(tokens[1::width]):
            return None
        # '(' stamp ')' with no other parenthesis: python-can's float(token[1:-1])
        stamps_text = ' '.join(tokens[0::width])
        if stamps_text.count('(') != lines or stamps_text.count(')') != lines \
                or stamps_text.count(') (') != lines - 1 or stamps_text[0] != '(' \
                or stamps_text[-1] != ')':
            return None
        stamps_inside = stamps_text[1:-1].split(') (')
        ids = tokens[2::width]
        data = tokens[4::width]
        if max(map(len, data)) > 16:  # more than 8 bytes: python-can's DLC check
            return None
        try:
            stamps = list(map(float, stamps_inside))
            payloads = list(map(bytes.fromhex, data))
            arbitration_ids = self._arbitration_ids(ids)
        except (ValueError, KeyError):
            return None
        total = sum(stamps)  # NaN when any stamp is NaN or infinite
        if total - total != 0.0 or min(stamps) < 0.0 or max(stamps) >= STAMP_END:
            return None
        return list(zip(stamps, arbitration_ids, payloads, map((3).__lt__, map(len, ids)),
                        repeat(False), repeat(False)))

    def _arbitration_ids(self, ids: List[str]) -> List[int]:
        """Return int(ID, 16) of each; KeyError or ValueError when one is no plain ID."""
        known = self._ids
        try:
            return list(map(known.__getitem__, ids))
        except KeyError:
            pass
        if len(known) > IDS_KEPT:
            known.clear()
        for text in set(ids).difference(known):
            value = int(text, 16)
            if 0 <= value < _FLAGS:  # python-can's mask changes nothing below the flags
                known[text] = value
        return list(map(known.__getitem__, ids))
