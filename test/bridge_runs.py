# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge started as users start it: a params file, the installed executable, an slcan peer.

What the start-up tests share: write a params file around an slcan peer (the test plays the
USB-CAN adapter), run the installed ``bridge`` on it, check that nothing reached the adapter,
and build a BridgeNode in-process to read the error a start refuses with.
"""
from __future__ import annotations

import itertools
import os
from pathlib import Path
import subprocess

import pytest
from rclpy.parameter import Parameter

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.ros.bridge_node import BridgeNode
from executables import bridge_executable
from helpers import wait_for
from slcan_peer import SlcanPeer

_ids = itertools.count()


def slcan_yaml(peer: SlcanPeer, body: str, bitrate: int = 500000) -> str:
    """Return a params file's text: ``body`` (indented parameters) and a ``can`` on the peer."""
    return (f'{body}    can: {{interface: slcan, channel: {peer.channel}, bitrate: {bitrate},'
            ' options: [sleep_after_open=0], reconnect_period: 0.2}\n')


def slcan_params(peer: SlcanPeer) -> dict:
    """Return node parameters for a bus on the peer: quick reconnects and diagnostics."""
    return {'can.interface': 'slcan', 'can.channel': peer.channel,
            'can.options': ['sleep_after_open=0'], 'can.reconnect_period': 0.2,
            'diagnostics_period': 0.2}


def run_bridge(tmp_path: Path, text: str, *args: str,
               env: dict | None = None) -> subprocess.CompletedProcess:
    """Run the installed bridge on the params file ``text`` to its end (30 s at most)."""
    params = tmp_path / f'params_{next(_ids)}.yaml'
    params.write_text(text)
    return subprocess.run([bridge_executable(), '--ros-args', '--params-file', str(params),
                           *args], capture_output=True, text=True, timeout=30,
                          env=env or dict(os.environ))


def assert_nothing_reached(peer: SlcanPeer) -> None:
    """Check that the adapter got no command, no frame: a marker now is the first thing read."""
    with open(peer.channel, 'wb', buffering=0) as tty:  # as the bridge would have written
        tty.write(b'V\r')
    wait_for(lambda: 'V' in peer.commands, timeout=5.0, what='the marker line')
    assert peer.commands == ['V'] and peer.received() == [] and not peer.is_open


def stopped_before_the_adapter(tmp_path: Path, body: str, tag: str) -> str:
    """Start the bridge on a serial adapter; assert exit 2, no traceback, nothing sent."""
    peer = SlcanPeer(symlink=tmp_path / f'ttyACM_{tag}')
    try:
        proc = run_bridge(tmp_path, slcan_yaml(peer, body))
        assert proc.returncode == 2, proc.stderr
        assert 'Traceback' not in proc.stderr, proc.stderr
        assert_nothing_reached(peer)  # no heartbeat, not even the channel opened
    finally:
        peer.shutdown()
    return proc.stderr


def node_error(context, overrides: dict) -> str:
    """Build a BridgeNode on a virtual bus with ``overrides``; return its ConfigError's text."""
    params = {'can.interface': 'virtual', 'can.channel': f'checks-{os.getpid()}-{next(_ids)}',
              **overrides}
    with pytest.raises(ConfigError) as info:
        BridgeNode(context=context, namespace=f'checks_{next(_ids)}',
                   parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    return str(info.value)
