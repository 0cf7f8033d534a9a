# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
An slcan adapter that sends bytes without a line end (issue 26 point 9), over a real pty.

The red team's adapter spewed garbage with no CR or BEL: the receive buffer grew without
limit (and was searched again for each chunk: a core at 100 %), while the CAN bus status
stayed OK. Now a run longer than ``MAX_LINE`` is dropped and counted, the buffer stays
bounded, the frames after it are read, and the CAN bus status is WARN naming the garbage.
"""
from __future__ import annotations

import threading
import time

from sensor_msgs.msg import BatteryState
import pytest

from ams_can_bridge.can_io import core
from ams_can_bridge.can_io.slcan import BulkReadSlcanBus, MAX_LINE
from ams_can_bridge.protocols.common import Frame
from bridge_runs import slcan_params
from shared import bms16_status, level, values
from slcan_peer import frame_to_slcan, SlcanPeer

NOISE = bytes(range(0x20, 0x7F)) * 64  # printable, no CR (0x0D) or BEL (0x07): 6 KB
FRAME = Frame(0x123, b'\x01\x02\x03')


@pytest.mark.parametrize('bulk, size', [(True, 2_000_000), (False, 60_000)],
                         ids=['block reader', "python-can's reader"])
def test_garbage_is_dropped_and_counted_and_the_buffer_stays_bounded(bulk, size):
    with SlcanPeer() as peer:
        bus = BulkReadSlcanBus(peer.channel, bulk_read=bulk, sleep_after_open=0, timeout=0.5)
        peer.wait_open()

        def spew() -> None:  # an adapter: the garbage, then a line end and a frame
            for _ in range(size // len(NOISE)):
                if not peer.send_raw(NOISE):
                    return
            # a line end closes the last piece of it (a short junk line python-can ignores)
            peer.send_raw(b'\r' + frame_to_slcan(FRAME))

        writer = threading.Thread(target=spew, daemon=True)
        try:
            writer.start()
            largest = 0
            deadline = time.monotonic() + 60.0
            got = None
            while got is None and time.monotonic() < deadline:
                msg = bus.recv(0.005)  # a short wait: the buffer is looked at often
                largest = max(largest, len(bus._buffer))
                if msg is not None:
                    got = Frame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id)
            writer.join(timeout=5.0)
            assert got == FRAME, 'the frame after the garbage is read'
            assert largest <= MAX_LINE + 4096, largest  # at most a line and one read
            assert bus.garbage_bytes >= size - MAX_LINE - 2 * len(NOISE)
            assert bus.garbage_lines >= 1
        finally:
            bus.shutdown()


def test_the_bus_status_is_warn_while_the_adapter_sends_garbage(
        rig_factory, tmp_path, monkeypatch, capfd):
    monkeypatch.setattr(core, 'GARBAGE_WARN_S', 1.5)  # back to OK 1.5 s after the last byte
    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN3')
    try:
        h = rig_factory(dict(slcan_params(peer), devices=['bms16']),
                        topics={'bms16/battery_state': BatteryState}, wait_connected=False)
        h.status('CAN bus', lambda s: values(s)['state'] == 'connected' and level(s) == 0)
        peer.wait_open()
        for _ in range(40):
            assert peer.send_raw(NOISE)
        status = h.status('CAN bus', lambda s: level(s) == 1)
        assert values(status)['state'] == 'connected' and values(status)['reconnects'] == '0'
        assert int(values(status)['garbage bytes dropped']) >= 40 * len(NOISE) - MAX_LINE
        assert 'without a line end' in status.message and 'baud rate' in status.message
        # frames still flow beside it
        assert peer.send_raw(b'\r')
        h.wait(lambda: peer.send(Frame(500, bms16_status(0, 61, 500, 0, 20)))
               and any(m.present and abs(m.percentage - 0.61) < 1e-6
                       for m in h.messages('bms16/battery_state')))
        # and once it stops, the status is OK again
        h.status('CAN bus', lambda s: level(s) == 0
                 and values(s)['garbage bytes dropped'] != '0', timeout=10.0)
    finally:
        peer.shutdown()
    err = capfd.readouterr().err
    assert 'bytes without a line end from the adapter dropped' in err
    assert 'Traceback' not in err
