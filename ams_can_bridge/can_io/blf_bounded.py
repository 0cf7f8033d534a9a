# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
python-can's BLF reader with a bound on what one log object may inflate to.

python-can's ``BLFReader`` inflates each LOG_CONTAINER object whole (``zlib`` without a
limit) and keeps an object cut at a container's end in a tail that grows with every
following container, so a small crafted ``.blf`` can take gigabytes of memory. Loggers
write containers of 128 KiB inflated (python-can's writer, Vector's tools); this reader
refuses, naming the file and the object's offset, a container that declares or inflates to
more than ``MAX_OBJECT_BYTES``, and an object that does not end within that many bytes.
Everything else is python-can's own parsing (``_parse_container``).
"""
from __future__ import annotations

from typing import Any, Generator, Iterator
import zlib

import can
from can.io import blf

MAX_OBJECT_BYTES = 16 << 20  # 128 x the 128 KiB containers loggers write


class BlfObjectTooLarge(can.io.blf.BLFParseError):
    """An object of the log would inflate beyond MAX_OBJECT_BYTES."""


class BoundedBLFReader(can.BLFReader):
    """``can.BLFReader`` that refuses objects inflating beyond ``MAX_OBJECT_BYTES``."""

    def __init__(self, file: Any, limit: int = MAX_OBJECT_BYTES, **kwargs: Any) -> None:
        """Open the file as python-can does; objects are bounded by ``limit`` bytes."""
        super().__init__(file, **kwargs)
        self.name = str(getattr(self.file, 'name', file))
        self.limit = limit

    def _refuse(self, offset: int, what: str) -> BlfObjectTooLarge:
        return BlfObjectTooLarge(
            f'{self.name}: the object at byte {offset} {what}, beyond the '
            f'{self.limit >> 20} MiB an object may inflate to (a corrupt or crafted log)')

    def __iter__(self) -> Generator[can.Message, None, None]:
        """Yield the messages; raise BlfObjectTooLarge on an object beyond the bound."""
        for inflated in self.containers():
            yield from self._parse_container(inflated)
        self.stop()

    def containers(self) -> Iterator[bytes]:
        """
        Yield each LOG_CONTAINER's bytes, inflated, as python-can's ``__iter__`` reads them.

        What follows is python-can's ``_parse_container`` (or log2bag's own parsing of the
        same bytes, ``offline/blf_frames.py``). Raises BlfObjectTooLarge beyond the bound.
        """
        base = blf.OBJ_HEADER_BASE_STRUCT
        while True:
            offset = self.file.tell()
            data = self.file.read(base.size)
            if not data:
                break
            signature, _, _, obj_size, obj_type = base.unpack(data)
            if signature != b'LOBJ':
                raise blf.BLFParseError()
            obj_data = self.file.read(obj_size - base.size)
            self.file.read(obj_size % 4)  # padding
            if obj_type != blf.LOG_CONTAINER:
                continue
            method, declared = blf.LOG_CONTAINER_STRUCT.unpack_from(obj_data)
            packed = obj_data[blf.LOG_CONTAINER_STRUCT.size:]
            if declared > self.limit:
                raise self._refuse(offset, f'declares {declared} bytes inflated')
            if method == blf.NO_COMPRESSION:
                inflated = packed
            elif method == blf.ZLIB_DEFLATE:
                inflated = zlib.decompressobj().decompress(packed, self.limit + 1)
            else:
                blf.LOG.warning('Unknown compression method (%d)', method)
                continue
            if len(inflated) > self.limit:
                raise self._refuse(offset, f'inflates to more than {self.limit} bytes')
            if len(self._tail) + len(inflated) > self.limit:
                raise self._refuse(offset, 'continues an object that does not end within '
                                   f'{self.limit} bytes')
            yield inflated
