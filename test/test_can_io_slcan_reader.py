# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge's slcan block reader (can_io/slcan.py) against python-can's own slcan reader.

Both read the same bytes from a pty adapter (test/slcan_peer.py); the block reader must give
exactly the messages python-can's gives, whatever way the bytes are cut into writes, and
must do it in far fewer reads of the port.
"""
from __future__ import annotations

import time

import can
from can.interfaces.slcan import slcanBus
import pytest

from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.can_io.slcan import BulkReadSlcanBus, open_bulk_slcan
from ams_can_bridge.protocols.common import Frame
from slcan_peer import frame_to_slcan, SlcanPeer

FRAMES = [Frame(0x100 + i, bytes(range(i % 9)), i % 3 == 0) for i in range(40)]
STREAM = b''.join(frame_to_slcan(f) for f in FRAMES)


def _open(cls: type, peer: SlcanPeer) -> can.BusABC:
    bus = cls(peer.channel, sleep_after_open=0, timeout=0.5)
    peer.wait_open()
    return bus


def _receive(bus: can.BusABC, count: int, timeout: float = 5.0) -> list[Frame]:
    frames: list[Frame] = []
    deadline = time.monotonic() + timeout
    while len(frames) < count and time.monotonic() < deadline:
        msg = bus.recv(0.2)
        if msg is not None:
            frames.append(Frame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id))
    return frames


@pytest.mark.parametrize('cut', [len(STREAM), 1, 7, 27, 100])
@pytest.mark.parametrize('cls', [BulkReadSlcanBus, slcanBus])
def test_same_messages_however_the_bytes_are_cut(cls, cut):
    """40 frames written in pieces of `cut` bytes (lines split mid-way) come out whole."""
    with SlcanPeer() as peer:
        bus = _open(cls, peer)
        try:
            for i in range(0, len(STREAM), cut):
                peer.send_raw(STREAM[i:i + cut])
                if cut < len(STREAM) and i % (cut * 8) == 0:
                    time.sleep(0.002)  # some pieces arrive after the reader has drained
            assert _receive(bus, len(FRAMES)) == FRAMES
        finally:
            bus.shutdown()


def test_block_reader_reads_the_port_far_less_often():
    """The point of it: one read takes a burst, not one byte per call."""
    with SlcanPeer() as peer:
        bus = _open(BulkReadSlcanBus, peer)
        reads = []
        real_read = bus.serialPortOrig.read

        def counting_read(size: int = 1) -> bytes:
            reads.append(size)
            return real_read(size)
        bus.serialPortOrig.read = counting_read
        try:
            peer.send_raw(STREAM)
            time.sleep(0.1)  # the whole burst waits in the pty
            assert _receive(bus, len(FRAMES)) == FRAMES
        finally:
            bus.shutdown()
    # python-can's reader: one read per byte (len(STREAM) ~ 800); this one a handful.
    assert len(reads) <= 5, reads


def test_undecodable_line_fails_once_then_frames_flow():
    """Line noise that is not text raises once (the bridge counts an unreadable line)."""
    with SlcanPeer() as peer:
        bus = _open(BulkReadSlcanBus, peer)
        try:
            peer.send_raw(b't1\xff\xfe2\r' + frame_to_slcan(FRAMES[1]))
            with pytest.raises(ValueError):
                bus.recv(1.0)
            assert _receive(bus, 1) == [FRAMES[1]]
        finally:
            bus.shutdown()


def test_error_bell_ends_a_line_like_python_can():
    """An adapter's BEL (command refused) ends a line; the next frame is intact."""
    with SlcanPeer() as peer:
        bus = _open(BulkReadSlcanBus, peer)
        try:
            peer.send_raw(b'\a' + frame_to_slcan(FRAMES[4]))
            assert _receive(bus, 1) == [FRAMES[4]]
        finally:
            bus.shutdown()


def test_recv_times_out_on_a_silent_port():
    with SlcanPeer() as peer:
        bus = _open(BulkReadSlcanBus, peer)
        try:
            t0 = time.monotonic()
            assert bus.recv(0.2) is None
            # a read waits at most the port's timeout (0.5 s) past recv's own
            assert 0.15 <= time.monotonic() - t0 < 1.5
        finally:
            bus.shutdown()


def test_open_merges_python_can_config_like_can_bus():
    """open_bulk_slcan takes what can.Bus(interface='slcan') takes (bitrate -> 'S6')."""
    with SlcanPeer() as peer:
        bus = open_bulk_slcan(peer.channel, bitrate=500000, sleep_after_open=0)
        try:
            peer.wait_open()
            assert isinstance(bus, BulkReadSlcanBus)
            assert peer.bitrate_command == 'S6'
        finally:
            bus.shutdown()


class _Sink:
    def __init__(self) -> None:
        self.frames: list[tuple[int, bytes, bool]] = []

    def __call__(self, arbitration_id: int, data: bytes, extended: bool, stamp: float) -> None:
        self.frames.append((arbitration_id, data, extended))


@pytest.mark.parametrize('bulk', [True, False])
def test_can_io_opens_the_reader_the_parameter_names(bulk):
    with SlcanPeer() as peer:
        sink = _Sink()
        io = CanIo(BusConfig(interface='slcan', channel=peer.channel, slcan_bulk_read=bulk,
                             options={'sleep_after_open': 0}), sink)
        io.start()
        try:
            peer.wait_open()
            deadline = time.monotonic() + 5.0
            while io._bus is None and time.monotonic() < deadline:
                time.sleep(0.01)
            # both open the port exclusively (BulkReadSlcanBus); False reads as python-can
            assert type(io._bus) is BulkReadSlcanBus and io._bus._bulk is bulk
            peer.send_raw(STREAM)
            while len(sink.frames) < len(FRAMES) and time.monotonic() < deadline:
                time.sleep(0.01)
            assert [Frame(*f) for f in sink.frames] == FRAMES
        finally:
            io.stop()


def test_falls_back_to_python_cans_reader_if_its_internals_change(monkeypatch, caplog):
    """A python-can release without the line buffer this reader fills: warn, read as before."""
    original = slcanBus.__init__

    def renamed_buffer(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self._buffer = None  # as if python-can had renamed it
    monkeypatch.setattr(slcanBus, '__init__', renamed_buffer)
    with SlcanPeer() as peer:
        bus = _open(BulkReadSlcanBus, peer)
        try:
            assert bus._bulk is False
            assert "python-can's own byte-per-call reader" in caplog.text
        finally:
            bus._buffer = bytearray()
            bus.shutdown()
