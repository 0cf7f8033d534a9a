# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The frames of a CAN log, as python-can reads it, with bad entries counted instead of fatal.

python-can's readers are generators: one unparsable line ends the iteration. For the line
formats whose reader can start again in the middle of a file (candump .log, .trc, .csv,
.asc), a bad line is counted and reading goes on after it; in a binary log (.blf) nothing
after a corrupt object can be trusted, so reading stops there and the summary says so.

A log cut short (a copy that stopped, a logger that lost power) says so in ``truncated``:
a text log whose last line has no end (that line is not read: a cut line can still parse,
as a frame with part of its data), an .asc that opened a "Begin TriggerBlock" without its
closing "End TriggerBlock" (can-utils' log2asc and some CANoe versions write neither: such
a file is complete), a .blf shorter than its header says. python-can's .trc reader logs one
warning per line it cannot parse instead of raising: those are counted here as bad entries,
not printed one by one; the records that are no frame (PCAN's Warng, Error, ER, ST, EC, EV:
bus warnings, error frames, status, events) are counted apart, as ``other``.
An entry whose timestamp is no time (NaN, infinite, before 1970, from 2038-01-19 on: see
``stamp_problem``) is a bad entry too: counted and skipped, never stamped otherwise.
"""
from __future__ import annotations

import itertools
import logging
import os
import re
from typing import Any, Iterable, Iterator, List

import can

from ams_can_bridge.can_io.blf_bounded import BoundedBLFReader
from ams_can_bridge.can_io.replay import open_log, STAMP_END, stamp_problem
from ams_can_bridge.errors import LogFileError
from ams_can_bridge.offline.blf_frames import BlfFrames
from ams_can_bridge.offline.candump_frames import CandumpFrames
from ams_can_bridge.offline.frame_tuples import Frame, message_frame
from ams_can_bridge.input_files import file_problem

# Readers that re-read a header when iterated anew: a blank line stands in for it.
_NEEDS_HEADER_LINE = (can.CSVReader, can.ASCReader)
_RESUMABLE = (can.CanutilsLogReader, can.TRCReader) + _NEEDS_HEADER_LINE
_LINE_COUNT_CHUNK = 1 << 20
_ASC_END = b'end triggerblock'
_ASC_BEGIN = b'begin triggerblock'
_ASC_HEAD = 1 << 16  # bytes of an .asc searched for its Begin TriggerBlock (in its header)
# A line that is a frame entry (python-can's ASC_MESSAGE_REGEX, any first token as the time)
_ASC_FRAME = re.compile(r'\s*\S+\s+(\d+\s+(\w+\s+(Tx|Rx)|ErrorFrame)|CANFD)',
                        re.ASCII | re.IGNORECASE)
# python-can's TRCReader logs these (one per line) and goes on: a line it cannot parse is
# a bad entry, a record of another type (not a frame) is counted apart
_TRC_LOGGER = 'can.io.trc'
_TRC_BAD = 'TRCReader: Failed to parse'
_TRC_OTHER = 'TRCReader: Unsupported type'


class _FileLines:
    """A file the reader iterates as its own: these lines, and the file's other attributes."""

    _file: Any
    _lines: Iterator[str]

    def __iter__(self) -> Iterator[str]:
        return self._lines

    def __next__(self) -> str:
        return next(self._lines)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._file, name)


class _CompleteLines(_FileLines):
    """
    A text file's lines up to the last one that ends with a newline (a cut line is left).

    For an .asc (``watch``), a line that looks like a frame entry is held as the owner's
    ``pending`` until the reader yields its message; python-can's ASCReader drops the lines
    it cannot read without a word (a NaN, inf or 1e308 timestamp): one still pending when
    the next line is read is a bad entry.
    """

    def __init__(self, file: Any, owner: 'LogFrames', watch: bool = False) -> None:
        self._file = file
        self._owner = owner
        self._lines = self._complete(watch)

    def _complete(self, watch: bool) -> Iterator[str]:
        owner = self._owner
        for number, line in enumerate(self._file, 1):
            if not line.endswith('\n'):
                owner.cut_line = line
                return
            if watch:
                owner.drop_pending()
                if _ASC_FRAME.match(line):
                    owner.pending = (number, line)
            yield line


class _CountTrcErrors(logging.Filter):
    """Count (and silence) the TRC reader's per-line parse messages as bad entries."""

    def __init__(self, owner: 'LogFrames') -> None:
        super().__init__()
        self.owner = owner

    def filter(self, record: logging.LogRecord) -> bool:
        text = str(record.msg)
        if text.startswith(_TRC_BAD):
            self.owner.bad += 1
            self.owner.last_bad = record.getMessage()
            return False
        if text.startswith(_TRC_OTHER):
            self.owner.other += 1
            self.owner.other_kinds.update(str(arg) for arg in record.args or ())
            return False
        return True


class _Lines(_FileLines):
    """A text file with lines put in front, that the reader iterates (and closes) as its own."""

    def __init__(self, first: list[str], file: Any) -> None:
        self._file = file
        self._lines: Iterator[str] = itertools.chain(first, file)


class LogFrames:
    """
    Iterate the messages of a log; count and describe the entries python-can cannot parse.

    ``total`` estimates the number of entries (lines of a text log, objects of a BLF) for a
    progress display; ``bad`` counts the entries skipped, ``stopped`` says why reading ended
    early (empty when the log was read to its end).
    """

    def __init__(self, path: str) -> None:
        """Open the log; raise LogFileError naming what is wrong."""
        problem = file_problem(path)
        if problem:
            raise LogFileError(f'log file {path!r} {problem}')
        try:
            self.reader = open_log(path)
        except ValueError as exc:
            raise LogFileError(f'log file {path!r}: {exc} (python-can reads .asc, .blf, '
                               '.csv, .log (candump -L), .trc, .mf4)') from None
        except Exception as exc:  # a BLF whose header is not one
            raise LogFileError(f'log file {path!r} cannot be opened: {exc}') from None
        self.path = path
        self.total = self._estimate_total()
        self.bad = 0
        self.last_bad = ''
        self.bad_stamps = 0  # of the bad entries: a timestamp that is no time
        self.other = 0  # records that are no frame (a .trc's status, warnings, events)
        self.other_kinds: set[str] = set()
        self.stopped = ''
        self.truncated = ''  # why the log looks cut short ('' = it ends as it should)
        self.cut_line: str | None = None
        self.pending: tuple[int, str] | None = None  # an .asc frame line not yet yielded
        if isinstance(self.reader, _RESUMABLE) and hasattr(self.reader, 'file'):
            # a duck-typed text file: python-can reads it line by line only
            self.reader.file = _CompleteLines(  # type: ignore[assignment]
                self.reader.file, self, watch=isinstance(self.reader, can.ASCReader))
        self._trc_filter: _CountTrcErrors | None = None
        if isinstance(self.reader, can.TRCReader):
            self._trc_filter = _CountTrcErrors(self)
            trc_logger = logging.getLogger(_TRC_LOGGER)
            # 'Unsupported type' is INFO: the logger must let it through to be counted
            self._trc_level = trc_logger.level
            trc_logger.setLevel(logging.INFO)
            trc_logger.addFilter(self._trc_filter)

    def _estimate_total(self) -> int | None:
        count = getattr(self.reader, 'object_count', None)  # BLF header
        if isinstance(count, int):
            return count
        if not isinstance(self.reader, _RESUMABLE):
            return None
        lines = 0
        with open(self.path, 'rb') as stream:
            for chunk in iter(lambda: stream.read(_LINE_COUNT_CHUNK), b''):
                lines += chunk.count(b'\n')
        return lines

    def __iter__(self) -> Iterator[can.Message]:
        """Yield every message; bad entries are counted (and skipped where possible)."""
        messages = iter(self.reader)
        while True:
            try:
                msg = next(messages)
            except StopIteration:
                self.drop_pending()
                self._check_end()
                return
            except Exception as exc:
                if not isinstance(self.reader, _RESUMABLE):
                    self._stop_at(exc)
                    return
                self.bad += 1
                self.last_bad = f'{type(exc).__name__}: {exc}'
                if isinstance(self.reader, _NEEDS_HEADER_LINE):
                    self.reader.file = _Lines(['\n'], self.reader.file)  # type: ignore[assignment]
                messages = iter(self.reader)
                continue
            self.pending = None
            if self.accepted(msg):
                yield msg

    def frames(self) -> Iterator[Frame]:
        """
        Return the frames as ``Frame`` tuples: the frames, values and counts of iterating.

        What log2bag's converter takes, without a ``can.Message`` per frame: a candump .log
        is read by log2bag's own reader (``candump_frames``), a .blf's containers parsed by
        its own (``blf_frames``), the other formats by python-can. The own readers' frames
        come a list a chunk, flattened in C (no Python generator resumed per frame).
        """
        lines = getattr(self.reader, 'file', None)
        if isinstance(lines, _CompleteLines) and isinstance(self.reader, can.CanutilsLogReader):
            return itertools.chain.from_iterable(self._candump_chunks(lines))
        if isinstance(self.reader, BoundedBLFReader):
            return itertools.chain.from_iterable(self._blf_chunks(self.reader))
        return map(message_frame, self)

    def _candump_chunks(self, lines: _CompleteLines) -> Iterator[Iterable[Frame]]:
        """
        Yield a candump .log's frames, a list a chunk, read by the own reader.

        From a chunk on that is not text in the file's encoding, python-can reads the rest
        (it raises there, after the lines before it).
        """
        own = CandumpFrames(self, lines._file)
        try:
            yield from own.chunks()
        except UnicodeDecodeError:
            lines._file.seek(0)
            rest = _CompleteLines(lines._file, self)
            setattr(self.reader, 'file', rest)  # python-can reads on after the lines read
            for _ in itertools.islice(rest, own.lines_read):
                pass
            yield map(message_frame, self)
            return
        self._check_end()

    def _blf_chunks(self, reader: BoundedBLFReader) -> Iterator[List[Frame]]:
        """Yield a .blf's frames, a list a container, parsed by the own parsing."""
        try:
            yield from BlfFrames(self, reader).chunks()
        except Exception as exc:
            self._stop_at(exc)
            return
        self._check_end()

    def _stop_at(self, exc: Exception) -> None:
        """Count the entry a binary log's reader raised at; reading ends there."""
        self.bad += 1
        self.last_bad = f'{type(exc).__name__}: {exc}'
        self.stopped = f'stopped at a bad entry ({self.last_bad})'

    def accepted(self, msg: can.Message) -> bool:
        """Tell whether a message read is a frame; count it as a bad entry when it is not."""
        stamp = msg.timestamp
        # most entries: a time a ROS stamp holds (NaN fails both comparisons)
        problem = '' if 0.0 <= stamp < STAMP_END else stamp_problem(stamp)
        if problem:
            self.bad_stamp(msg.arbitration_id, stamp, problem)
            return False
        if (not msg.is_fd and not msg.is_remote_frame and not msg.is_error_frame
                and len(msg.data) != min(msg.dlc, 8)):  # an .asc's 'd f 01 02'
            self.bad += 1
            self.last_bad = (f'frame 0x{msg.arbitration_id:X} at timestamp '
                             f'{msg.timestamp!r}: data length {msg.dlc} (its DLC) with '
                             f'{len(msg.data)} data bytes')
            return False
        return True

    def bad_stamp(self, arbitration_id: int, stamp: float, problem: str) -> None:
        """Count an entry whose timestamp is no time (``stamp_problem`` says why)."""
        self.bad += 1
        self.bad_stamps += 1
        self.last_bad = f'frame 0x{arbitration_id:X} at timestamp {stamp!r}: {problem}'

    def drop_pending(self) -> None:
        """Count the .asc frame line the reader read without yielding a frame (bad entry)."""
        if self.pending is not None:
            number, line = self.pending
            self.pending = None
            self.bad += 1
            self.last_bad = f'line {number}: {line.strip()[:60]!r} is no frame python-can reads'

    def _check_end(self) -> None:
        """Set ``truncated`` when the log was read to an end that is not its proper end."""
        if self.cut_line is not None:
            self.truncated = (f'the log is cut short: its last line has no end and was not '
                              f'read ({self.cut_line.strip()[:60]!r})')
            return
        size = os.path.getsize(self.path)
        header_size = getattr(self.reader, 'file_size', None)  # BLF header
        if isinstance(self.reader, can.BLFReader) and isinstance(header_size, int) \
                and size < header_size:
            self.truncated = (f'the log is cut short: {size} of the {header_size} bytes its '
                              'header announces')
        elif isinstance(self.reader, can.ASCReader):
            with open(self.path, 'rb') as stream:
                opened = _ASC_BEGIN in stream.read(_ASC_HEAD).lower()
                stream.seek(max(0, size - 256))
                tail = stream.read().strip().lower()
            if opened and not tail.endswith(_ASC_END):
                self.truncated = ('the log is cut short: it ends without the closing '
                                  '"End TriggerBlock" line')

    def close(self) -> None:
        """Close the file (and stop counting the TRC reader's messages)."""
        if self._trc_filter is not None:
            trc_logger = logging.getLogger(_TRC_LOGGER)
            trc_logger.removeFilter(self._trc_filter)
            trc_logger.setLevel(self._trc_level)
            self._trc_filter = None
        self.reader.stop()
