"""
The frames of a CAN log, as python-can reads it, with bad entries counted instead of fatal.

python-can's readers are generators: one unparsable line ends the iteration. For the line
formats whose reader can start again in the middle of a file (candump .log, .trc, .csv,
.asc), a bad line is counted and reading goes on after it; in a binary log (.blf) nothing
after a corrupt object can be trusted, so reading stops there and the summary says so.
"""
from __future__ import annotations

import itertools
import os
from typing import Any, Iterator

import can

from ams_can_bridge.can_io.replay import open_log
from ams_can_bridge.errors import LogFileError

# Readers that re-read a header when iterated anew: a blank line stands in for it.
_NEEDS_HEADER_LINE = (can.CSVReader, can.ASCReader)
_RESUMABLE = (can.CanutilsLogReader, can.TRCReader) + _NEEDS_HEADER_LINE
_LINE_COUNT_CHUNK = 1 << 20


class _Lines:
    """A text file with lines put in front, that the reader iterates (and closes) as its own."""

    def __init__(self, first: list[str], file: Any) -> None:
        self._file = file
        self._lines = itertools.chain(first, file)

    def __iter__(self) -> Iterator[str]:
        return self._lines

    def __next__(self) -> str:
        return next(self._lines)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._file, name)


class LogFrames:
    """
    Iterate the messages of a log; count and describe the entries python-can cannot parse.

    ``total`` estimates the number of entries (lines of a text log, objects of a BLF) for a
    progress display; ``bad`` counts the entries skipped, ``stopped`` says why reading ended
    early (empty when the log was read to its end).
    """

    def __init__(self, path: str) -> None:
        """Open the log; raise LogFileError naming what is wrong."""
        if not os.path.isfile(path):
            raise LogFileError(f'log file {path!r} does not exist')
        if not os.access(path, os.R_OK):
            raise LogFileError(f'log file {path!r} is not readable')
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
        self.stopped = ''

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
                return
            except Exception as exc:
                self.bad += 1
                self.last_bad = f'{type(exc).__name__}: {exc}'
                if not isinstance(self.reader, _RESUMABLE):
                    self.stopped = f'stopped at a bad entry ({self.last_bad})'
                    return
                if isinstance(self.reader, _NEEDS_HEADER_LINE):
                    self.reader.file = _Lines(['\n'], self.reader.file)
                messages = iter(self.reader)
                continue
            yield msg

    def close(self) -> None:
        """Close the file."""
        self.reader.stop()
