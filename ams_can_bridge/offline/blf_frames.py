# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's own parsing of a ``.blf``'s CAN messages: python-can's frames, without a can.Message.

The containers are python-can's, read and inflated by ``BoundedBLFReader.containers()``
(its bounds included); this module parses their bytes as python-can's
``BLFReader._parse_container``/``_parse_data`` do, to the same frames and the same tail
carried into the next container. A run of CAN_MESSAGE or CAN_MESSAGE2 objects with
identical headers (the same type, size, header version 1 and time unit: what loggers
write) is unpacked at once (``struct.iter_unpack``, then ``map``/``zip`` in C) in windows of
``RUN`` objects; any other object is parsed one by one as python-can does: a CAN_MESSAGE or
CAN_MESSAGE2 here (the same fields), an error frame or a CAN FD message by python-can's own
``_parse_data`` on that object's bytes, anything else skipped as python-can skips it.

Timestamps are python-can's: ``float(Decimal(t) * Decimal('1e-5' or '1e-9'))`` plus the
file's start is ``t / 10**5`` (or ``10**9``) in Python's exactly rounded integer division,
plus the start.
"""
from __future__ import annotations

import operator
import struct
import sys
from itertools import repeat
from typing import cast, Generator, Iterator, List

import can
from can.io import blf

from ams_can_bridge.can_io.blf_bounded import BoundedBLFReader
from ams_can_bridge.can_io.replay import STAMP_END, stamp_problem
from ams_can_bridge.offline.frame_tuples import Counts, Frame, message_frame

RUN = 256  # objects unpacked at once, at most
_WINDOW = 8  # objects unpacked at once after a run that stopped short
_MASK = 0x1FFFFFFF
_EXT = blf.CAN_MSG_EXT
_REMOTE = blf.REMOTE_FLAG
_TEN_MICS = 1  # the object header's flags: 10 us units; anything else: ns (python-can's)
_MESSAGES = (blf.CAN_MESSAGE, blf.CAN_MESSAGE2)
_PYTHON_CAN = (blf.CAN_ERROR_EXT, blf.CAN_FD_MESSAGE, blf.CAN_FD_MESSAGE_64)
_BASE = blf.OBJ_HEADER_BASE_STRUCT
_V1 = blf.OBJ_HEADER_V1_STRUCT
_V2 = blf.OBJ_HEADER_V2_STRUCT
_MESSAGE = blf.CAN_MSG_STRUCT
# An object in a run, CAN_MESSAGE(2) with a v1 header: bytes 0-19 equal in every object (the
# base header and the v1 header's flags: five 32-bit words), the time at 24 (64 bits), the
# message's flags at 34, DLC at 35, ID at 36 (a 32-bit word), data at 40
_HEADER_WORDS = 5
_FLAGS_AT = 34
_DLC_AT = 35
_ID_WORD = 9
_DATA_AT = 40
_FLAGS_FROM = 0x20000000  # an ID from here has bits python-can masks off
_RUNS = sys.byteorder == 'little'  # the columns are the machine's words
_READS = 512  # bytes past an object's start python-can may read of it (FD64: 40 + 40 + 255)


class BlfFrames:
    """The frames of a BLF as ``Frame`` tuples, python-can's values, a list per container."""

    def __init__(self, counts: Counts, reader: BoundedBLFReader) -> None:
        """Parse what ``reader`` (opened, its header read) inflates."""
        self.counts = counts
        self.reader = reader
        self.start = reader.start_timestamp
        self._window = RUN

    def chunks(self) -> Iterator[List[Frame]]:
        """
        Yield each container's frames, a list a container.

        Raise what python-can's reader raises, after the frames before it.
        """
        reader = self.reader
        for inflated in reader.containers():
            data = reader._tail + inflated if reader._tail else inflated
            out: List[Frame] = []
            try:
                self._parse(data, out)
            except struct.error:  # python-can: not enough bytes left for a struct
                pass
            except Exception:
                yield out
                raise
            reader._tail = data[reader._pos:]
            yield out
        reader.stop()

    def _parse(self, data: bytes, out: List[Frame]) -> None:
        """python-can's ``_parse_data`` loop, appending frames; ``reader._pos`` as it sets it."""
        reader = self.reader
        end = len(data)
        pos = 0
        while True:
            reader._pos = pos
            try:
                pos = data.index(b'LOBJ', pos, pos + 8)
            except ValueError:
                if pos + 8 > end:
                    return
                raise blf.BLFParseError('Could not find next object') from None
            _, _, version, size, kind = _BASE.unpack_from(data, pos)
            if not size:  # python-can would parse this object again, for ever
                raise blf.BLFParseError('an object of 0 bytes (less than its own header)')
            after = pos + size
            if after > end:
                return  # the object continues in the next container
            if version == 1 and kind in _MESSAGES and size >= 48 and not size % 8 and _RUNS:
                ran = self._run(data, pos, size, out)
                if ran:
                    pos += ran * size
                    continue
            if version == 1:
                flags, _, _, stamp = _V1.unpack_from(data, pos + _BASE.size)
                at = pos + _BASE.size + _V1.size
            elif version == 2:
                flags, _, _, stamp = _V2.unpack_from(data, pos + _BASE.size)
                at = pos + _BASE.size + _V2.size
            else:
                blf.LOG.warning('Unknown object header version (%d)', version)
                pos = after
                continue
            if kind in _MESSAGES:
                self._message(data, at, self._stamp(flags, stamp), out)
            elif kind in _PYTHON_CAN:
                self._python_can(data, pos, size, out)
            pos = after

    def _stamp(self, flags: int, stamp: int) -> float:
        return (stamp / 100000 if flags == _TEN_MICS else stamp / 1000000000) + self.start

    def _message(self, data: bytes, at: int, stamp: float, out: List[Frame]) -> None:
        """One CAN_MESSAGE or CAN_MESSAGE2: python-can's fields, LogFrames' stamp check."""
        _, flags, dlc, can_id, can_data = _MESSAGE.unpack_from(data, at)
        arbitration_id = can_id & _MASK
        if not 0.0 <= stamp < STAMP_END:
            self.counts.bad_stamp(arbitration_id, stamp, stamp_problem(stamp))
            return
        remote = bool(flags & _REMOTE)
        out.append((stamp, arbitration_id, b'' if remote else can_data[:dlc],
                    bool(can_id & _EXT), False, remote))

    def _python_can(self, data: bytes, pos: int, size: int, out: List[Frame]) -> None:
        """Parse an error frame or CAN FD message with python-can's ``_parse_data``."""
        reader = self.reader
        search = reader._pos
        parse = cast(Generator[can.Message, None, None], can.BLFReader._parse_data(
            reader, data[pos:pos + size + _READS]))
        try:
            msg = next(parse, None)
        finally:
            parse.close()
            reader._pos = search  # a struct.error leaves python-can's tail from here
        if msg is not None and self.counts.accepted(msg):
            out.append(message_frame(msg))

    def _run(self, data: bytes, pos: int, size: int, out: List[Frame]) -> int:
        """
        Parse the objects from ``pos`` that repeat the first one's header; return how many.

        0: the first object is none for a run (it goes one by one).

        Each field is a column of the objects' bytes (a strided slice); the window (objects
        at once) starts at 8 after a run that stopped short and doubles up to RUN: a
        container of mixed objects costs a few objects looked at twice, not RUN.
        """
        count = min(self._window, (len(data) - pos) // size)
        chunk = data[pos:pos + count * size]
        words = memoryview(chunk).cast('I')  # little-endian (checked by the caller)
        step = size // 4
        headers = [words[word::step].tolist() for word in range(_HEADER_WORDS)]
        stamps = memoryview(chunk).cast('Q')[3::size // 8].tolist()
        divisor = 100000 if headers[4][0] == _TEN_MICS else 1000000000
        times = list(map(operator.add, map(operator.truediv, stamps, repeat(divisor)),
                         repeat(self.start)))
        flags = chunk[_FLAGS_AT::size]
        if any(column.count(column[0]) != count for column in headers) \
                or max(flags) & _REMOTE or min(times) < 0.0 or max(times) >= STAMP_END:
            count = _same(headers, flags, times)
            self._window = _WINDOW
            if not count:
                return 0
            del times[count:]
        elif self._window < RUN:
            self._window *= 2
        can_ids = words[_ID_WORD::step].tolist()[:count]
        lengths = chunk[_DLC_AT::size][:count]
        if max(lengths) > 8:
            lengths = bytes(map(min, lengths, repeat(8)))
        starts = range(_DATA_AT, count * size, size)
        payloads = map(chunk.__getitem__, map(slice, starts, map(operator.add, starts, lengths)))
        if max(can_ids) < _FLAGS_FROM:  # no extended ID: python-can's mask changes nothing
            out += zip(times, can_ids, payloads, repeat(False), repeat(False), repeat(False))
        else:
            out += zip(times, map(operator.and_, can_ids, repeat(_MASK)), payloads,
                       map(_EXT.__le__, can_ids), repeat(False), repeat(False))
        return count


def _same(headers: List[List[int]], flags: bytes, times: List[float]) -> int:
    """Count the leading objects with the first one's header, no remote, a good stamp."""
    firsts = [column[0] for column in headers]
    for index, (*header, flag, stamp) in enumerate(zip(*headers, flags, times)):
        if header != firsts or flag & _REMOTE or not 0.0 <= stamp < STAMP_END:
            return index
    return len(times)
