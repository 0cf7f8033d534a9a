# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Ctrl-C and SIGTERM end the installed ``bridge`` cleanly whatever it is doing.

During heavy traffic (the fake adapter writes frames as fast as the pty takes them) and
during a service call that waits for the AMS: exit code 0 within 2 s of the signal, no
traceback, and the adapter told to close its channel. A params file the bridge cannot use
(missing, not YAML, wrong types) ends it with a message and exit code 2, no traceback.
"""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import threading
import time

import pytest
from std_srvs.srv import Trigger

from ams_can_bridge.protocols.common import Frame
from executables import bridge_executable
from helpers import wait_for
from shared import FRAMES
from slcan_peer import SlcanPeer

EXIT_WITHIN = 2.0  # s from the signal to the exit (issue 9)


def start_bridge(tmp_path: Path, peer: SlcanPeer, ns: str) -> subprocess.Popen:
    params = tmp_path / 'signals.yaml'
    params.write_text(
        '/**:\n  ros__parameters:\n    devices: [ams, ivt_s, evms3, bms16, sma]\n'
        '    commands_allowed: true\n    commands_enabled: true\n'
        '    ams: {command_timeout: 30.0}\n'
        f'    can: {{interface: slcan, channel: {peer.channel}, bitrate: 500000,'
        ' options: [sleep_after_open=0]}\n')
    return subprocess.Popen(
        [bridge_executable(), '--ros-args', '-r', f'__ns:=/{ns}', '--params-file',
         str(params)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=dict(os.environ),
        text=True)


def stop_and_check(proc: subprocess.Popen, peer: SlcanPeer, signum: int) -> None:
    opened = max(i for i, c in enumerate(peer.commands) if c[0] in 'OL')
    sent = time.monotonic()
    proc.send_signal(signum)
    try:
        stdout, stderr = proc.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        stdout, stderr = proc.communicate(timeout=10)
        raise AssertionError(f'the bridge ignored {signal.Signals(signum).name}: {stderr}')
    took = time.monotonic() - sent
    assert proc.returncode == 0, stdout + stderr
    assert 'Traceback' not in stderr and 'Traceback' not in stdout, stderr
    assert took < EXIT_WITHIN, f'{took:.2f} s from {signal.Signals(signum).name} to exit'
    wait_for(lambda: 'C' in peer.commands[opened + 1:], timeout=5.0,
             what=f"'C' after 'O' (commands: {peer.commands})")
    assert not peer.is_open


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_during_heavy_traffic(tmp_path, signum):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_flood')
    proc = start_bridge(tmp_path, peer, f'flood_{os.getpid()}_{signum}')
    stop = threading.Event()
    count = [0]

    def flood() -> None:
        while not stop.is_set():
            for frame in FRAMES + [Frame(0x300, bytes(3))]:  # valid and malformed
                if peer.send(frame):
                    count[0] += 1
    try:
        peer.wait_open(timeout=30)
        flooder = threading.Thread(target=flood, daemon=True)
        flooder.start()
        wait_for(lambda: count[0] >= 2000, timeout=30, what='2000 frames into the bridge')
        assert proc.poll() is None
        stop_and_check(proc, peer, signum)
    finally:
        stop.set()
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
        peer.shutdown()


@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_during_a_waiting_call(ros, tmp_path, signum):  # noqa: F811 (fixture)
    node, executor = ros
    ns = f'waiting_{os.getpid()}_{signum}'
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_wait')
    proc = start_bridge(tmp_path, peer, ns)
    try:
        peer.wait_open(timeout=30)
        client = node.create_client(Trigger, f'/{ns}/ams/enable_ts')
        assert client.wait_for_service(timeout_sec=30)
        future = client.call_async(Trigger.Request())
        # the bridge carries ENABLE_TS (2) in its heartbeats: the call is waiting now
        wait_for(lambda: any(f.arbitration_id == 0x305 and f.data[0] & 0x0F == 2
                             for f in peer.received()), timeout=10, what='ENABLE_TS carried')
        executor.spin_once(timeout_sec=0.05)
        assert not future.done()
        stop_and_check(proc, peer, signum)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
        peer.shutdown()


@pytest.mark.parametrize('text, expected', [
    (None, 'does not exist: give the path of a params file'),
    ('/**:\n  ros__parameters:\n    devices: [bms16\n', 'Error parsing'),
    ('/**:\n  ros__parameters:\n    devices: bms16\n    diagnostics_period: fast\n',
     "diagnostics_period = 'fast' must be a number"),
], ids=['missing', 'not-yaml', 'wrong-types'])
def test_a_bad_params_file_is_a_message_and_exit_2(tmp_path, text, expected):
    params = tmp_path / 'bad.yaml'
    if text is not None:
        params.write_text(text)
    proc = subprocess.run([bridge_executable(), '--ros-args', '--params-file', str(params)],
                          capture_output=True, text=True, timeout=60, env=dict(os.environ))
    assert proc.returncode == 2, proc.stderr
    assert 'Traceback' not in proc.stderr, proc.stderr
    assert 'cannot start' in proc.stderr and expected in proc.stderr, proc.stderr
    assert proc.stderr.count(expected) == 1, proc.stderr  # each problem named once
