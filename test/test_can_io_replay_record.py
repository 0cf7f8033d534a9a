# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Replay of log files through CanIo ('replay' interface) and recording of the raw bus."""
import time
import uuid

import can
import pytest

from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.errors import CanSendError
from ams_can_bridge.protocols.common import Frame
from helpers import wait_for

# A known sequence: (offset s, id, extended, data); 0.1 s apart, 0.5 s in all.
SEQUENCE = [
    (0.0, 0x300, False, b'\x01\x02\x03\x04\x05\x06\x07'),
    (0.1, 0x521, False, b'\x00\x00\x00\x00\x03\xE8'),
    (0.2, 0x1E, True, b'\x10\x20\x30\x40\x50\x60\x70\x80'),
    (0.3, 0x1F4, False, b''),
    (0.4, 0x311, False, b'\x21' + bytes(7)),
    (0.5, 0x300, False, b'\xFF'),
]


def write_log(path, sequence=SEQUENCE, start=1_700_000_000.0):
    """Write sequence with python-can's own writer for the extension of path."""
    writer = can.Logger(str(path))
    for offset, arbitration_id, extended, data in sequence:
        writer.on_message_received(can.Message(
            timestamp=start + offset, arbitration_id=arbitration_id, is_extended_id=extended,
            data=data, channel='can0'))
    writer.stop()
    return path


class Sink:
    """Collect on_frame calls with a monotonic arrival time."""

    def __init__(self):
        self.frames = []
        self.arrivals = []

    def __call__(self, arbitration_id, data, extended, stamp):
        self.frames.append((arbitration_id, extended, data))
        self.arrivals.append(time.monotonic())


def replay(path, rate, sink, **kwargs):
    io = CanIo(BusConfig(interface='replay', channel=str(path), replay_rate=rate,
                         reconnect_period=0.1, **kwargs), sink)
    io.start()
    return io


EXPECTED = [(i, e, d) for _, i, e, d in SEQUENCE]


@pytest.mark.parametrize('suffix', ['.log', '.asc', '.blf', '.csv'])
def test_replay_as_fast_as_possible_plays_every_frame_in_order(tmp_path, suffix):
    path = write_log(tmp_path / f'drive{suffix}')
    sink = Sink()
    io = replay(path, 0, sink)
    try:
        wait_for(lambda: io.status().state == 'replay finished', what='replay finished')
        assert sink.frames == EXPECTED
        status = io.status()
        assert status.frames_in == len(SEQUENCE)
        assert f'{len(SEQUENCE)} frames played' in status.reason
        assert status.hardware_id == f'replay:{path}'
        assert sink.arrivals[-1] - sink.arrivals[0] < 0.4  # no real-time pacing at 0
    finally:
        io.stop()


@pytest.mark.parametrize('suffix', ['.log', '.asc'])
def test_replay_real_time_keeps_the_timing(tmp_path, suffix):
    path = write_log(tmp_path / f'drive{suffix}')
    sink = Sink()
    io = replay(path, 1.0, sink)
    try:
        wait_for(lambda: io.status().state == 'replay finished', what='replay finished')
        assert sink.frames == EXPECTED
        span = sink.arrivals[-1] - sink.arrivals[0]
        assert 0.45 <= span < 2.0, span        # 0.5 s in the log; late is tolerated
        # Never early: each frame at or after its offset from the first (late is fine).
        for (offset, *_), arrival in zip(SEQUENCE, sink.arrivals):
            assert arrival - sink.arrivals[0] >= offset - 0.05
    finally:
        io.stop()


def test_replay_rate_scales_time(tmp_path):
    # 2 s of log at 4x: paced to 0.5 s. The bounds say which rate played (1x would take 2 s,
    # as fast as possible ~0 s), with 1 s of room for a loaded machine: no speed figure.
    stretched = [(offset * 4, *rest) for offset, *rest in SEQUENCE]
    path = write_log(tmp_path / 'drive.log', stretched)
    sink = Sink()
    io = replay(path, 4.0, sink)
    try:
        wait_for(lambda: io.status().state == 'replay finished', what='replay finished')
        assert sink.frames == EXPECTED
        # never early: each frame at or after a quarter of its log offset
        for (offset, *_), arrival in zip(stretched, sink.arrivals):
            assert arrival - sink.arrivals[0] >= offset / 4 - 0.05
        assert sink.arrivals[-1] - sink.arrivals[0] < 2.0 * 0.75  # clearly not 1x
    finally:
        io.stop()


def test_missing_file_is_an_error_and_replays_once_it_appears(tmp_path):
    path = tmp_path / 'later.log'
    sink = Sink()
    io = replay(path, 0, sink)
    try:
        wait_for(lambda: io.status().state == 'error', what='error state')
        assert str(path) in io.status().reason
        assert sink.frames == []
        write_log(path)
        wait_for(lambda: io.status().state == 'replay finished', what='replay finished')
        assert sink.frames == EXPECTED
    finally:
        io.stop()


def test_unreadable_format_is_an_error(tmp_path):
    path = tmp_path / 'drive.xyz'
    path.write_text('not a log\n')
    io = replay(path, 0, Sink())
    try:
        wait_for(lambda: io.status().state == 'error', what='error state')
        assert 'xyz' in io.status().reason
    finally:
        io.stop()


def test_replay_with_filters_only_passes_configured_ids(tmp_path):
    path = write_log(tmp_path / 'drive.log')
    sink = Sink()
    io = CanIo(BusConfig(interface='replay', channel=str(path), replay_rate=0), sink,
               filters=[(0x300, False), (0x1E, True)])
    io.start()
    try:
        wait_for(lambda: io.status().state == 'replay finished', what='replay finished')
        assert [f[0] for f in sink.frames] == [0x300, 0x1E, 0x300]
    finally:
        io.stop()


@pytest.mark.parametrize('suffix', ['.asc', '.log', '.blf'])
def test_record_gets_frames_in_and_out(tmp_path, suffix):
    # Digits above 65535 in the channel name: BLF stores a channel *number* (ushort) and
    # python-can derives it from the name; the recording must not depend on the name.
    channel = f'rec_{uuid.uuid4().hex[:8]}_999999'
    record = tmp_path / f'rec{suffix}'
    other = can.Bus(interface='virtual', channel=channel)
    sink = Sink()
    io = CanIo(BusConfig(interface='virtual', channel=channel, record=str(record)), sink)
    io.start()
    try:
        wait_for(lambda: io.status().state == 'connected', what='connected')
        other.send(can.Message(arbitration_id=0x111, data=b'\x01', is_extended_id=False))
        wait_for(lambda: len(sink.frames) == 1, what='frame in')
        io.send(Frame(0x222, b'\x02\x03'))
        io.send(Frame(0x1ABCDE, b'\x04', True))
        assert other.recv(2.0).arbitration_id == 0x222
    finally:
        io.stop()
        other.shutdown()
    messages = list(can.LogReader(str(record)))
    got = [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in messages]
    assert got == [(0x111, False, b'\x01'), (0x222, False, b'\x02\x03'),
                   (0x1ABCDE, True, b'\x04')]
    if suffix in ('.asc', '.blf'):   # formats that keep the direction
        assert [m.is_rx for m in messages] == [True, False, False]
    stamps = [m.timestamp for m in messages]
    assert stamps == sorted(stamps)


def test_record_while_replaying_and_send_during_replay(tmp_path):
    source = write_log(tmp_path / 'drive.log')
    record = tmp_path / 'copy.asc'
    sink = Sink()
    io = CanIo(BusConfig(interface='replay', channel=str(source), replay_rate=1.0,
                         record=str(record)), sink)
    io.start()
    try:
        wait_for(lambda: len(sink.frames) >= 1, what='first replayed frame')
        io.send(Frame(0x005, b'\x10\x01'))   # accepted: recorded, no bus behind it
        wait_for(lambda: io.status().state == 'replay finished', what='replay finished')
        with pytest.raises(CanSendError):
            io.send(Frame(0x005, b'\x10\x02'))
    finally:
        io.stop()
    messages = list(can.LogReader(str(record)))
    rx = [(m.arbitration_id, m.is_extended_id, bytes(m.data)) for m in messages if m.is_rx]
    tx = [(m.arbitration_id, bytes(m.data)) for m in messages if not m.is_rx]
    assert rx == EXPECTED
    assert tx == [(0x005, b'\x10\x01')]


class FullDisk:
    """A can.Logger stand-in whose disk fills after the first frame (and fails its close)."""

    def __init__(self, path):
        self.written, self.stops = [], 0

    def on_message_received(self, msg):
        if self.written:
            raise OSError(28, 'No space left on device')
        self.written.append(msg.arbitration_id)

    def stop(self):
        self.stops += 1
        raise OSError(28, 'No space left on device')


def test_a_failing_recording_ends_itself_and_the_bus_goes_on(tmp_path, monkeypatch, caplog):
    writers = []
    monkeypatch.setattr(can, 'Logger', lambda path: writers.append(FullDisk(path))
                        or writers[-1])
    channel = f'full_{uuid.uuid4().hex[:8]}'
    other = can.Bus(interface='virtual', channel=channel)
    sink = Sink()
    io = CanIo(BusConfig(interface='virtual', channel=channel,
                         record=str(tmp_path / 'rec.asc')), sink)
    io.start()
    try:
        wait_for(lambda: io.status().state == 'connected', what='connected')
        for n in range(3):
            other.send(can.Message(arbitration_id=0x100 + n, data=b'', is_extended_id=False))
        wait_for(lambda: len(sink.frames) == 3, what='every frame, recording or not')
        io.send(Frame(0x222, b'\x02'))  # sent although the recording failed
        assert other.recv(2.0).arbitration_id == 0x222
    finally:
        io.stop()  # the close is not tried again on the failed file: no error raised
        other.shutdown()
    assert [w.written for w in writers] == [[0x100]]
    assert writers[0].stops == 1  # closed once, at the failure, to keep what was written
    stopped = [r for r in caplog.records if 'CAN recording to' in r.getMessage()]
    assert len(stopped) == 1 and 'No space left' in stopped[0].getMessage()


def test_bad_record_path_fails_at_start(tmp_path):
    io = CanIo(BusConfig(interface='virtual', channel='x',
                         record=str(tmp_path / 'no_dir' / 'rec.asc')), Sink())
    with pytest.raises(ValueError, match='can.record'):
        io.start()
    io.stop()


def test_corrupt_line_ends_the_replay_with_the_reason(tmp_path):
    path = tmp_path / 'bad.log'
    path.write_text('(1700000000.000000) can0 300#0102\ngarbage line here\n'
                    '(1700000000.100000) can0 301#03\n')
    sink = Sink()
    io = replay(path, 0, sink)
    try:
        wait_for(lambda: io.status().state == 'replay finished', what='replay finished')
        assert sink.frames == [(0x300, False, b'\x01\x02')]
        assert '1 frames played' in io.status().reason
        assert 'bad entry' in io.status().reason
    finally:
        io.stop()
