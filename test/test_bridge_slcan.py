# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The installed ``bridge`` executable on slcan over a pty: the test plays the USB-CAN adapter.

The bridge runs as a subprocess (its params file written here), inherits the test's
ROS_DOMAIN_ID / ROS_AUTOMATIC_DISCOVERY_RANGE, and a subscriber in this process checks the
topics; SIGINT must end it with exit code 0 and no traceback.
"""
from __future__ import annotations

import itertools
import os
from pathlib import Path
import signal
import subprocess
import time

from diagnostic_msgs.msg import DiagnosticArray
import pytest
from sensor_msgs.msg import BatteryState

from ams_can_bridge.protocols.common import Frame
from executables import bridge_executable
from helpers import interrupt, wait_for
from shared import FRAMES
from slcan_peer import SlcanPeer

BATTERY = ['ams', 'ivt', 'evms3', 'bms16', 'sma']


def params_file(path: Path, channel: str) -> Path:
    path.write_text(f"""/**:
  ros__parameters:
    can:
      interface: slcan
      channel: {channel}
      bitrate: 500000
      options: [sleep_after_open=0]
      reconnect_period: 0.2
    diagnostics_period: 0.5
    devices: [ams, ivt, evms3, bms16, sma]
    ivt:
      type: ivt_s
    evms3:
      stale_timeout: 2
""")
    return path


def frames_round(n: int) -> list[Frame]:
    """Return FRAMES with the IVT-S and AMS message counters at n: live devices count up."""
    ivt, ams = FRAMES[0], FRAMES[1]
    return [Frame(ivt.arbitration_id, ivt.data[:1] + bytes([n & 0x0F]) + ivt.data[2:]),
            Frame(ams.arbitration_id, ams.data[:5] + bytes([n & 0xFF]) + ams.data[6:])
            ] + FRAMES[2:]


def test_installed_bridge_on_slcan(ros, tmp_path):
    node, executor = ros
    ns = f'slcan_{os.getpid()}'
    got: dict[str, list] = {name: [] for name in BATTERY}
    diags: list = []
    for name in BATTERY:
        node.create_subscription(BatteryState, f'/{ns}/{name}/battery_state',
                                 lambda m, n=name: got[n].append(m), 50)
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_bridge')
    hardware_id = f'slcan:{peer.channel}'
    node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: diags.append(m) if any(s.hardware_id == hardware_id for s in m.status)
        else None, 50)
    params = params_file(tmp_path / 'bridge.yaml', peer.channel)
    proc = subprocess.Popen(
        [bridge_executable(), '--ros-args', '-r', f'__ns:=/{ns}', '--params-file',
         str(params)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=dict(os.environ), text=True)
    try:
        peer.wait_open(timeout=30)
        assert peer.bitrate_command == 'S6'  # 500 kbit/s
        deadline = time.monotonic() + 30
        rounds = itertools.count()
        while time.monotonic() < deadline and not all(
                any(m.present for m in msgs) for msgs in got.values()):
            for frame in frames_round(next(rounds)):
                peer.send(frame)
            executor.spin_once(timeout_sec=0.1)
        missing = [n for n, msgs in got.items() if not any(m.present for m in msgs)]
        assert not missing, f'no battery_state from {missing}'
        assert any(abs(m.current - 12.0) < 1e-4 for m in got['ivt'])
        assert any(abs(m.percentage - 0.66) < 1e-6 for m in got['ams'])
        assert any(abs(m.voltage - 345.6) < 1e-3 for m in got['evms3'])
        assert any(abs(m.percentage - 0.81) < 1e-6 for m in got['bms16'])
        assert any(abs(m.current + 15.3) < 1e-4 for m in got['sma'])
        # Every device healthy (level OK) and saying its state in its message; the frames
        # keep coming meanwhile, so no device goes stale while we wait.
        expected = {'ams': 'IDLE', 'ivt': '12.00 A', 'evms3': 'RUNNING', 'bms16': 'SoC 81 %',
                    'sma': '51.2 V', 'CAN bus': 'connected'}

        prefix = f'{ns}/ams_can_bridge: '  # the namespace is in the names (issue 18.4)

        def healthy(array) -> bool:
            statuses = {s.name: s for s in array.status}
            return set(statuses) == {f'{prefix}{n}' for n in expected} and all(
                statuses[f'{prefix}{n}'].level == b'\x00'
                and word in statuses[f'{prefix}{n}'].message
                for n, word in expected.items())
        while time.monotonic() < deadline and not any(healthy(a) for a in diags):
            for frame in frames_round(next(rounds)):
                peer.send(frame)
            executor.spin_once(timeout_sec=0.1)
        assert diags, 'no /diagnostics from the bridge'
        assert any(healthy(a) for a in diags), [
            (s.name, s.level, s.message) for s in diags[-1].status]
        assert proc.poll() is None
    finally:
        output = interrupt(proc)
        peer.shutdown()
    assert proc.returncode == 0, output
    assert 'Traceback' not in output, output
    assert 'evms3 (evms3): 0x1E' in output, output  # startup summary names the devices and IDs


def test_bridge_exits_2_on_bad_parameters(tmp_path):
    params = tmp_path / 'bad.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [pack]\n    pack:\n'
                      '      type: zeva\n')
    proc = subprocess.run([bridge_executable(), '--ros-args', '--params-file', str(params)],
                          capture_output=True, text=True, timeout=60, env=dict(os.environ))
    assert proc.returncode == 2
    assert 'pack.type' in proc.stderr and 'Traceback' not in proc.stderr


def test_bridge_names_every_bad_start_value_at_once(tmp_path):
    params = tmp_path / 'bad.yaml'
    params.write_text(
        '/**:\n  ros__parameters:\n    devices: [evms3, bms16]\n'
        '    can: {interface: virtual, channel: bad_values}\n'
        '    evms3:\n      config: {pack_capacity_ah: 7, balance_mode: sometimes}\n'
        '    bms16:\n      base_id: 5000\n      config: {shunt_size_a: 250}\n')
    proc = subprocess.run([bridge_executable(), '--ros-args', '--params-file', str(params)],
                          capture_output=True, text=True, timeout=60, env=dict(os.environ))
    assert proc.returncode == 2 and 'Traceback' not in proc.stderr
    assert '4 parameters need a change' in proc.stderr
    for reason in ('bms16.base_id = 5000 is out of range: allowed 0x0..0x7FF',
                   'evms3.config.pack_capacity_ah = 7 is off the step: allowed 5..1250 in '
                   'steps of 5',
                   "evms3.config.balance_mode = 'sometimes' is not allowed",
                   'bms16.config.shunt_size_a = 250 refused'):
        assert reason in proc.stderr, (reason, proc.stderr)


@pytest.mark.parametrize('when', ['running', 'starting'])
def test_sigterm_closes_the_channel_and_exits_0(ros, tmp_path, when):
    node, executor = ros
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_term')
    diags: list = []
    node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: diags.append(m) if any(s.hardware_id == f'slcan:{peer.channel}'
                                         for s in m.status) else None, 10)
    params = tmp_path / 'term.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [bms16]\n'
                      '    diagnostics_period: 0.2\n'
                      f'    can: {{interface: slcan, channel: {peer.channel}, bitrate: 500000,'
                      ' options: [sleep_after_open=0]}\n')
    proc = subprocess.Popen(
        [bridge_executable(), '--ros-args', '-r', f'__ns:=/term_{os.getpid()}',
         '--params-file', str(params)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=dict(os.environ), text=True)
    try:
        # 'starting': the bus opens inside the node's constructor, before the executor
        # exists; a signal right then must end the bridge as cleanly as one while it runs.
        peer.wait_open(timeout=30)
        opened = max(i for i, c in enumerate(peer.commands) if c[0] in 'OL')
        if when == 'running':
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and not diags:
                executor.spin_once(timeout_sec=0.1)
            assert diags, 'the bridge never published /diagnostics'
        proc.send_signal(signal.SIGTERM)
        try:
            stdout, stderr = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            stdout, stderr = proc.communicate(timeout=10)
        # the adapter was told to close the channel ('C') after it had been opened
        wait_for(lambda: 'C' in peer.commands[opened + 1:], timeout=5.0,
                 what=f"'C' after 'O' (commands: {peer.commands})")
        assert not peer.is_open
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
        peer.shutdown()
    assert proc.returncode == 0, stdout + stderr
    assert 'Traceback' not in stderr, stderr
