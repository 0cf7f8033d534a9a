# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's own BLF parsing gives python-can's frames and counts, object by object.

``LogFrames.frames()`` parses a ``.blf``'s containers with ``offline/blf_frames.py``
(runs of CAN_MESSAGE objects as columns) instead of python-can's ``_parse_data``. Each
test reads a file both ways (``shared.read_both_ways``: the same tuples, by ``repr``, and
the same counters): BLFs python-can's writer makes of every fixture .log (zlib and
uncompressed, one container and many, objects cut across containers), every kind of
message it writes, and files built object by object here with what a writer may put in
(version 2 headers, 10 us stamps, CAN_MESSAGE2, padding, unknown objects, FD-64 objects,
bad stamps), then cut short or corrupted. And BLFs nobody here or in python-can's writer
made: Toby Lorenz's vector_blf test files and a user's CAN FD log (``fixtures/python_can_blf``),
their frames written by hand from python-can's own expectations of them.
"""
from __future__ import annotations

from pathlib import Path
import random
import struct
import threading
import zlib

import can
from can.io import blf
import pytest

from ams_can_bridge.offline import blf_frames
from ams_can_bridge.offline.log_frames import LogFrames
from ams_can_bridge.probe.sources import read_log
from ams_can_bridge.probe.traffic import Traffic
from shared import bare_python_can, frame_counts, read_both_ways

FIXTURES = Path(__file__).parent / 'fixtures'
FIXTURE_LOGS = sorted(FIXTURES.rglob('*.log'))
START = 1790000000.0
WRITERS = {'zlib': {}, 'zlib_small_containers': {'max_container_size': 700},
           'uncompressed': {'compression_level': 0},
           'uncompressed_small_containers': {'compression_level': 0, 'max_container_size': 500}}


def blf_of(path: Path, messages, **options) -> Path:
    """Write messages with python-can's BLFWriter."""
    writer = can.BLFWriter(str(path), **options)
    for msg in messages:
        writer.on_message_received(msg)
    writer.stop()
    return path


def log_messages(path: Path) -> list[can.Message]:
    with can.LogReader(str(path)) as reader:
        return list(reader)


@pytest.mark.parametrize('writer', WRITERS)
def test_a_blf_of_every_fixture_log_reads_as_python_can_reads_it(tmp_path, writer):
    assert len(FIXTURE_LOGS) >= 10
    for log in FIXTURE_LOGS:
        path = blf_of(tmp_path / f'{log.parent.name}_{log.stem}.blf', log_messages(log),
                      **WRITERS[writer])
        got, found = read_both_ways(path)
        assert got == bare_python_can(path), log
        assert found == (0, '', 0, '', '', None) and len(got) == len(log_messages(log)), log


def every_kind() -> list[can.Message]:
    """Each kind of message python-can's BLF writer writes, standard and extended."""
    out = []
    for k in range(400):
        stamp = START + k * 0.0013
        out += [
            can.Message(timestamp=stamp, arbitration_id=0x100 + k, is_extended_id=False,
                        data=bytes(range(k % 9))),
            can.Message(timestamp=stamp, arbitration_id=0x18FF0000 + k, data=b'\x01\x02'),
            can.Message(timestamp=stamp, arbitration_id=0x1FFFFFFF, dlc=15, data=bytes(8)),
        ]
        if k % 7 == 0:
            out.append(can.Message(timestamp=stamp, arbitration_id=0x123, is_extended_id=False,
                                   is_remote_frame=True, dlc=4))
        if k % 11 == 0:
            out.append(can.Message(timestamp=stamp, is_error_frame=True, arbitration_id=0x5,
                                   data=b'\x07'))
        if k % 13 == 0:
            out.append(can.Message(timestamp=stamp, arbitration_id=0x7FF, is_extended_id=False,
                                   is_fd=True, bitrate_switch=True, data=bytes(range(24))))
        if k % 97 == 0:  # after 2038: a bad stamp
            out.append(can.Message(timestamp=2.2e9, arbitration_id=0x66, data=b'\x01'))
    return out


@pytest.mark.parametrize('writer', WRITERS)
def test_every_kind_of_message_python_can_writes(tmp_path, writer):
    got, (bad, last_bad, bad_stamps, *_) = read_both_ways(
        blf_of(tmp_path / 'kinds.blf', every_kind(), **WRITERS[writer]))
    assert bad == bad_stamps == 5 and 'past 2038' in last_bad
    assert len(got) == len(every_kind()) - 5
    kinds = {(eval(frame)[3], eval(frame)[4], eval(frame)[5]) for frame in got}
    assert kinds == {(False, False, False), (True, False, False), (False, False, True),
                     (True, True, False)}


def test_a_log_that_starts_past_2038_is_all_bad_stamps(tmp_path):
    messages = [can.Message(timestamp=3e9 + k, arbitration_id=k, data=b'\x01')
                for k in range(300)]
    got, (bad, _, bad_stamps, *_) = read_both_ways(blf_of(tmp_path / 'late.blf', messages))
    assert got == [] and bad == bad_stamps == 300


# --- files built object by object ---------------------------------------------------------

def obj(kind: int, body: bytes, stamp: int, version: int = 1, flags: int = 2,
        size: int | None = None, header_size: int | None = None) -> bytes:
    """One object: base header, a v1 or v2 header (any other version: a v1 one), body."""
    head = (blf.OBJ_HEADER_V2_STRUCT if version == 2 else blf.OBJ_HEADER_V1_STRUCT).pack(
        flags, 0, 0, stamp)
    length = blf.OBJ_HEADER_BASE_STRUCT.size + len(head) + len(body)
    size = length if size is None else size
    raw = blf.OBJ_HEADER_BASE_STRUCT.pack(
        b'LOBJ', header_size or blf.OBJ_HEADER_BASE_STRUCT.size + len(head), version, size,
        kind) + head + body
    return raw + bytes(size % 4)


def message(can_id: int, data: bytes, dlc: int | None = None, flags: int = 0) -> bytes:
    return blf.CAN_MSG_STRUCT.pack(1, flags, len(data) if dlc is None else dlc, can_id, data)


def fd64(can_id: int, data: bytes) -> bytes:
    return blf.CAN_FD_MSG_64_STRUCT.pack(1, 13, len(data), 0, can_id, 0, 0x1000, 0, 0, 0, 0,
                                         0, 0, 0, 0) + data


def container(payload: bytes, method: int = blf.ZLIB_DEFLATE) -> bytes:
    packed = zlib.compress(payload) if method == blf.ZLIB_DEFLATE else payload
    body = blf.LOG_CONTAINER_STRUCT.pack(method, len(payload)) + packed
    size = blf.OBJ_HEADER_BASE_STRUCT.size + len(body)
    return (blf.OBJ_HEADER_BASE_STRUCT.pack(b'LOBJ', 16, 1, size, blf.LOG_CONTAINER) + body
            + bytes(size % 4))


def crafted(path: Path, objects: bytes, cuts: list[int], method: int = blf.ZLIB_DEFLATE,
            ) -> Path:
    """
    Write a BLF: python-can's writer's header (its start: START), then ``objects``.

    The objects go in containers cut at ``cuts`` (offsets into ``objects``).
    """
    blf_of(path, [can.Message(timestamp=START, arbitration_id=1, data=b'\x00')])
    bounds = [0] + sorted(cuts) + [len(objects)]
    with open(path, 'ab') as stream:
        for begin, end in zip(bounds, bounds[1:]):
            stream.write(container(objects[begin:end], method))
    return path


def objects_of_every_shape(rng: random.Random, count: int) -> bytes:
    """Return runs of equal objects broken by every shape of object python-can reads or skips."""
    out = []
    stamp = 0
    for k in range(count):
        stamp += rng.randrange(0, 3_000_000)
        can_id = rng.choice((0x123, 0x7FF, 0x80000000 | 0x18FF50E5, 0xFFFFFFFF, 0x20000080))
        data = bytes(rng.randrange(256) for _ in range(8))
        dlc = rng.choice((0, 3, 8, 8, 8, 15))
        shape = rng.random()
        if shape < 0.85:  # the common run: what loggers write
            out.append(obj(blf.CAN_MESSAGE, message(can_id, data, dlc), stamp))
        else:
            out.append(rng.choice([
                obj(blf.CAN_MESSAGE2, message(can_id, data, dlc) + bytes(8), stamp),
                obj(blf.CAN_MESSAGE, message(can_id, data, dlc, flags=blf.REMOTE_FLAG), stamp),
                obj(blf.CAN_MESSAGE, message(can_id, data, dlc), stamp // 10000, flags=1),
                obj(blf.CAN_MESSAGE, message(can_id, data, dlc), stamp, version=2),
                obj(blf.CAN_MESSAGE2, message(can_id, data, dlc), stamp // 10000, version=2,
                    flags=1),
                obj(blf.CAN_MESSAGE, message(can_id, data, dlc, flags=blf.REMOTE_FLAG),
                    stamp // 10000, flags=1),
                obj(blf.CAN_MESSAGE, message(can_id, data, dlc), stamp, header_size=40),
                obj(blf.CAN_MESSAGE, message(can_id, data, dlc) + b'\xAA\xBB', stamp),  # pads
                obj(blf.CAN_MESSAGE, message(can_id, data, dlc), stamp, version=3),
                obj(blf.CAN_MESSAGE, message(can_id, data, dlc), stamp + 10 ** 19),  # 2038+
                obj(blf.GLOBAL_MARKER, bytes(40), stamp),
                obj(999, bytes(12), stamp),
                obj(blf.CAN_ERROR_EXT, blf.CAN_ERROR_EXT_STRUCT.pack(
                    1, 0, 0, 0, 0, 3, 0, can_id, 0, data), stamp),
                obj(blf.CAN_FD_MESSAGE, blf.CAN_FD_MSG_STRUCT.pack(
                    1, 0, 10, can_id, 0, 0, 1, 16, bytes(range(64))), stamp),
                obj(blf.CAN_FD_MESSAGE_64, fd64(can_id, bytes(range(20))), stamp),
            ]))
    return b''.join(out)


@pytest.mark.parametrize('method', [blf.ZLIB_DEFLATE, blf.NO_COMPRESSION])
@pytest.mark.parametrize('seed', range(3))
def test_objects_of_every_shape_across_containers(tmp_path, seed, method):
    rng = random.Random(seed)
    objects = objects_of_every_shape(rng, 3000)
    cuts = rng.sample(range(1, len(objects)), rng.randrange(0, 40))
    got, (bad, _, bad_stamps, stopped, *_) = read_both_ways(
        crafted(tmp_path / 'shapes.blf', objects, cuts, method))
    assert len(got) > 2000 and bad == bad_stamps > 0 and stopped == ''


def test_runs_are_parsed_without_python_can(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(blf_frames.BlfFrames, '_message',
                        lambda self, *args: calls.append(args))
    objects = b''.join(obj(kind, message(0x100 + k, bytes(8)) + extra, k * 1000)
                       for k in range(3000) for kind, extra in
                       [(blf.CAN_MESSAGE, b'')] * 3 + [(blf.CAN_MESSAGE2, bytes(8))])
    path = crafted(tmp_path / 'runs.blf', objects, [len(objects) // 3])
    frames = LogFrames(str(path))
    got = list(frames.frames())
    assert len(got) == 12001 and frame_counts(frames)[0] == 0
    assert calls == []  # a run of one object is a run too


@pytest.mark.parametrize('seed', range(3))
def test_a_blf_cut_anywhere_reads_as_python_can_reads_it(tmp_path, seed):
    rng = random.Random(seed)
    objects = objects_of_every_shape(rng, 600)
    whole = crafted(tmp_path / 'whole.blf', objects, rng.sample(range(1, len(objects)), 5),
                    rng.choice((blf.ZLIB_DEFLATE, blf.NO_COMPRESSION))).read_bytes()
    for cut in sorted(rng.sample(range(150, len(whole)), 25)):
        path = tmp_path / f'cut{cut}.blf'
        path.write_bytes(whole[:cut])
        read_both_ways(path)


@pytest.mark.parametrize('seed', range(3))
def test_a_corrupt_blf_reads_as_python_can_reads_it(tmp_path, seed):
    rng = random.Random(seed)
    method = rng.choice((blf.ZLIB_DEFLATE, blf.NO_COMPRESSION))
    whole = bytearray(crafted(tmp_path / 'whole.blf', objects_of_every_shape(rng, 600),
                              [7000, 15000], method).read_bytes())
    stops = 0
    for _ in range(25):
        bad = bytearray(whole)
        for _ in range(rng.randrange(1, 4)):
            bad[rng.randrange(200, len(bad))] = rng.randrange(256)
        path = tmp_path / 'bad.blf'
        path.write_bytes(bytes(bad))
        _, found = read_both_ways(path)
        stops += bool(found[3])
    assert stops > 0  # some of the damage stops the reading (a zlib error, no next object)


@pytest.mark.parametrize('kind', [blf.CAN_ERROR_EXT, blf.CAN_FD_MESSAGE_64])
def test_an_object_short_of_its_fields_at_a_containers_end(tmp_path, kind):
    # python-can reads past the object's end, out of the container (struct.error): the
    # object and what follows are kept and parsed again with the next container's bytes
    short = obj(kind, bytes(8), 5000)
    first = b''.join(obj(blf.CAN_MESSAGE, message(0x100 + k, bytes(8)), k) for k in range(9))
    rest = b''.join(obj(blf.CAN_MESSAGE, message(0x200 + k, bytes(8)), k) for k in range(9))
    objects = first + short + rest
    cut = len(first) + len(short)
    got, found = read_both_ways(crafted(tmp_path / 'short.blf', objects, [cut]))
    assert len(got) >= 19 and found[0] == 0


def test_garbage_between_objects_stops_the_reading_as_python_cans_does(tmp_path):
    objects = [obj(blf.CAN_MESSAGE, message(0x100, bytes(8)), k) for k in range(500)]
    objects.insert(300, b'not an object at all')
    got, (bad, last_bad, _, stopped, *_) = read_both_ways(
        crafted(tmp_path / 'garbage.blf', b''.join(objects), [], blf.NO_COMPRESSION))
    assert len(got) == 301 and bad == 1 and 'Could not find next object' in stopped


def test_an_unknown_compression_is_skipped_as_python_can_skips_it(tmp_path):
    path = crafted(tmp_path / 'method.blf', obj(blf.CAN_MESSAGE, message(0x1, bytes(8)), 5),
                   [])
    with open(path, 'ab') as stream:
        stream.write(container(obj(blf.CAN_MESSAGE, message(0x2, bytes(8)), 6), method=7))
        stream.write(container(obj(blf.CAN_MESSAGE, message(0x3, bytes(8)), 7)))
    got, _ = read_both_ways(path)
    assert [eval(frame)[1] for frame in got] == [1, 1, 3]


@pytest.mark.parametrize('size', [1, 8, 15, 20])
def test_an_object_smaller_than_its_fields_reads_as_python_can_reads_it(tmp_path, size):
    objects = [obj(blf.CAN_MESSAGE, message(0x100, bytes(8)), k) for k in range(9)]
    objects.insert(4, struct.pack('<4sHHLL', b'LOBJ', 16, 1, size, 1) + bytes(4)
                   + obj(blf.CAN_MESSAGE, message(0x200, bytes(8)), 99))
    got, _ = read_both_ways(crafted(tmp_path / 'small.blf', b''.join(objects), []))
    assert len(got) >= 5


def test_an_object_of_no_bytes_stops_the_reading(tmp_path):
    # python-can's _parse_data would parse this object again and again, for ever
    objects = b''.join(obj(blf.CAN_MESSAGE, message(0x100, bytes(8)), k) for k in range(5))
    path = crafted(tmp_path / 'small.blf', objects + struct.pack('<4sHHLL', b'LOBJ', 16, 1, 0,
                                                                 1) + bytes(40), [])
    frames = LogFrames(str(path))
    got = list(frames.frames())
    frames.close()
    assert len(got) == 6 and frames.bad == 1 and 'an object of 0 bytes' in frames.stopped


def test_probe_reads_such_a_log_to_the_object_and_stops(tmp_path):
    # probe read logs through python-can's parser: on this object it never returned
    objects = b''.join(obj(blf.CAN_MESSAGE, message(0x100, bytes(8)), k) for k in range(5))
    path = crafted(tmp_path / 'small.blf', objects + struct.pack('<4sHHLL', b'LOBJ', 16, 1, 0,
                                                                 1) + bytes(40), [])
    outcome: list[object] = []
    reader = threading.Thread(target=lambda: outcome.append(read_log(str(path))), daemon=True)
    reader.start()
    reader.join(30.0)
    assert not reader.is_alive(), 'probe still reading after 30 s'
    traffic = outcome[0]
    assert isinstance(traffic, Traffic) and traffic.frames == 6


# --- real BLF files (fixtures/python_can_blf/README.md) ------------------------------------

REAL_BLF = FIXTURES / 'python_can_blf'
# vector_blf's files: two objects each, stamped 2459565876.494607 (python-can's
# logformats_test.py), past what a ROS stamp holds: both counted as bad stamps
VECTOR_BLF = {'test_CanMessage.blf': 0x4444444, 'test_CanMessage2.blf': 0x4444444,
              'test_CanFdMessage.blf': 0x4444444, 'test_CanFdMessage64.blf': 0x15555555,
              'test_CanErrorFrameExt.blf': 0x19999999}


@pytest.mark.parametrize('name', sorted(VECTOR_BLF))
def test_vector_blf_files_read_as_python_can_reads_them(name):
    got, found = read_both_ways(REAL_BLF / name)
    assert got == []
    bad, last_bad, bad_stamps = found[:3]
    assert (bad, bad_stamps) == (2, 2)
    assert last_bad.startswith(f'frame 0x{VECTOR_BLF[name]:X} at timestamp 2459565876.494607: ')


def test_a_users_can_fd_blf_reads_as_python_can_reads_it():
    # python-can issue 1905: a CAN FD logger's file; its first message as python-can's
    # test_issue_1905 expects it (64 bytes: 48 x 0xFF, then 16 x 0x00)
    got, found = read_both_ways(REAL_BLF / 'issue_1905.blf')
    assert found == (0, '', 0, '', '', None)
    assert got == bare_python_can(REAL_BLF / 'issue_1905.blf') and len(got) > 1
    assert got[0] == repr((1735654183.491113, 0x6A9, b'\xff' * 48 + b'\x00' * 16, False,
                           False, False))
