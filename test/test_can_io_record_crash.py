# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
``can.record`` after a crash (issue 26 point 10): a real bridge process, killed with SIGKILL.

The red team killed a recording bridge and found its last buffer gone (15 frames of a .log,
270 of a .blf), still missing 3 s after the frames had arrived. The recording now reaches
the disk at least every ``FLUSH_PERIOD`` (1 s): here frames arrive over slcan (a pty, the
test plays the adapter), the bridge publishes the last of them (so all were recorded before
it), and 2.5 s later it is killed. Every frame must be in the file, which python-can reads.
"""
from __future__ import annotations

import os
import signal
import subprocess
import time

import can
import pytest
from sensor_msgs.msg import BatteryState

from ams_can_bridge.can_io.recording import FLUSH_PERIOD
from ams_can_bridge.protocols.common import Frame
from executables import bridge_executable
from shared import bms16_status
from slcan_peer import SlcanPeer

FRAMES = 100  # BMS16 status frames, SoC 0..99 %: a few kB, less than any writer's buffer


@pytest.mark.parametrize('suffix', ['.log', '.blf', '.asc'])
def test_a_killed_bridge_keeps_every_frame_older_than_a_second(
        ros, tmp_path, suffix):  # noqa: F811 (the fixture imported above)
    node, executor = ros
    ns = f'record_crash_{os.getpid()}_{suffix[1:]}'
    socs: list[float] = []
    node.create_subscription(BatteryState, f'/{ns}/bms16/battery_state',
                             lambda m: socs.append(round(m.percentage * 100)) if m.present
                             else None, 500)
    record = tmp_path / f'bus{suffix}'
    peer = SlcanPeer(symlink=tmp_path / 'ttyREC')
    params = tmp_path / 'record.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [bms16]\n'
                      f'    can: {{interface: slcan, channel: {peer.channel}, bitrate: 500000,'
                      f' options: [sleep_after_open=0], record: {record}}}\n')
    proc = subprocess.Popen(
        [bridge_executable(), '--ros-args', '-r', f'__ns:=/{ns}', '--params-file', str(params)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=dict(os.environ), text=True)
    sent = [Frame(500, bms16_status(0, soc, 520, 0, 20)) for soc in range(FRAMES)]
    try:
        peer.wait_open(timeout=30)
        # the first frame until the bridge publishes it (its subscription matched), then all
        deadline = time.monotonic() + 30
        while not socs and time.monotonic() < deadline:
            peer.send(sent[0])
            executor.spin_once(timeout_sec=0.1)
        assert socs, 'the bridge never published a battery_state'
        for frame in sent[1:]:
            assert peer.send(frame)
        while socs[-1] != FRAMES - 1 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
        assert socs[-1] == FRAMES - 1, 'the last frame was received (and so recorded)'
        time.sleep(FLUSH_PERIOD + 1.5)  # the promise: on the disk within a second
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
        stderr = proc.stderr.read() if proc.stderr else ''
        peer.shutdown()
    assert proc.returncode == -signal.SIGKILL, stderr
    with can.LogReader(str(record)) as reader:
        got = [bytes(m.data) for m in reader if m.arbitration_id == 500]
    expected = [frame.data for frame in sent]
    # the first frame may have been sent a few times until the bridge was heard
    assert got[-FRAMES:] == expected, f'{len(got)} frames in the file after the kill'
