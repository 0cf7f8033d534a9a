# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A log that would blow up on reading: a .blf container inflating far beyond what loggers write.

issue 34, 6: a 1 MB crafted .blf took log2bag to 2.1 GB (python-can's BLFReader inflates a
container whole). An object declaring, or inflating to, more than MAX_OBJECT_BYTES is refused
with the file and the object's byte offset named; memory stays near the bound.
"""
import tracemalloc
import zlib

import can
from can.io import blf
import pytest

from ams_can_bridge.can_io import blf_bounded
from ams_can_bridge.can_io.replay import open_log
from ams_can_bridge.errors import LogFileError
from ams_can_bridge.offline.log2bag import convert

BOMB_BYTES = 64 << 20  # inflated; about 64 kB compressed


def good_blf(path: str, frames: int = 5) -> str:
    with can.Logger(path) as log:
        for k in range(frames):
            log.on_message_received(can.Message(timestamp=1_790_000_000.0 + k * 0.01,
                                                arbitration_id=0x521, data=bytes(6)))
    return path


def container(inflated: bytes, declared: int) -> bytes:
    """Return a LOG_CONTAINER object: inflated zlib-compressed, declaring `declared` bytes."""
    packed = zlib.compress(inflated, 9)
    body = blf.LOG_CONTAINER_STRUCT.pack(blf.ZLIB_DEFLATE, declared) + packed
    size = blf.OBJ_HEADER_BASE_STRUCT.size + len(body)
    head = blf.OBJ_HEADER_BASE_STRUCT.pack(b'LOBJ', blf.OBJ_HEADER_BASE_STRUCT.size, 1, size,
                                           blf.LOG_CONTAINER)
    return head + body + bytes(size % 4)


def bomb(path: str, declared: int) -> int:
    """Append a container inflating to BOMB_BYTES after a good log; return its offset."""
    good_blf(path)
    with open(path, 'ab') as stream:
        offset = stream.tell()
        stream.write(container(bytes(BOMB_BYTES), declared))
    return offset


@pytest.mark.parametrize('declared', [BOMB_BYTES, 1000], ids=['declared', 'lying'])
def test_a_compressed_bomb_is_refused_naming_file_and_offset(tmp_path, declared):
    path = str(tmp_path / 'bomb.blf')
    offset = bomb(path, declared)
    reader = open_log(path)
    got = []
    tracemalloc.start()
    try:
        with pytest.raises(blf_bounded.BlfObjectTooLarge) as caught:
            for msg in reader:
                got.append(msg)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
        reader.stop()
    assert len(got) == 5  # the frames before it are read
    assert path in str(caught.value) and f'at byte {offset}' in str(caught.value)
    assert peak < 2 * blf_bounded.MAX_OBJECT_BYTES + (8 << 20), peak


def test_log2bag_names_the_bomb_and_exits_clean(tmp_path):
    path = str(tmp_path / 'only_bomb.blf')
    with can.Logger(path):
        pass
    with open(path, 'ab') as stream:
        stream.write(container(bytes(BOMB_BYTES), BOMB_BYTES))
    with pytest.raises(LogFileError) as caught:
        convert(path, str(tmp_path / 'bag'), {'devices': ['ivt_s']})
    assert 'only_bomb.blf' in str(caught.value) and 'at byte 144' in str(caught.value)
    assert not (tmp_path / 'bag').exists()


def test_objects_within_the_bound_read_as_python_can_reads_them(tmp_path):
    path = good_blf(str(tmp_path / 'fine.blf'), frames=3000)
    with can.BLFReader(path) as theirs:
        want = [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in theirs]
    reader = open_log(path)
    assert [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in reader] == want
    assert len(want) == 3000


def test_an_object_that_never_ends_is_refused(tmp_path):
    # an object header claiming more than the bound: every container after it is its tail
    path = good_blf(str(tmp_path / 'endless.blf'))
    endless = blf.OBJ_HEADER_BASE_STRUCT.pack(b'LOBJ', 16, 1, 0x7FFFFFF0, blf.CAN_MESSAGE)
    chunk = endless + bytes((1 << 20) - len(endless))
    with open(path, 'ab') as stream:
        for _ in range(20):
            stream.write(container(chunk, len(chunk)))
            chunk = bytes(1 << 20)
    reader = open_log(path)
    with pytest.raises(blf_bounded.BlfObjectTooLarge, match='does not end'):
        for _ in reader:
            pass
    reader.stop()
