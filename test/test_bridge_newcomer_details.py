# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Issue 38, point 10: the small things a first hour trips over, each kept fixed.

A bit rate written '500k' is one clear error (no WARN about a bit rate of 0 before it); a
stop while an slcan adapter settles after its port opened (python-can sleeps 2 s there) is
prompt and sends the adapter nothing.
"""
from __future__ import annotations

import os
import threading
import time

import pytest

from ams_can_bridge.can_io.config import BusConfig
from ams_can_bridge.can_io.core import CanIo
from ams_can_bridge.can_io.slcan import lock_serial_port
from ams_can_bridge.errors import ParamError
from ams_can_bridge.parameters import BUS_PARAMS, coerce
from bridge_runs import run_bridge, slcan_yaml
from slcan_peer import SlcanPeer

SETTLE = 6.0  # s: the adapter's wait after opening, far longer than a prompt stop


def test_a_bitrate_written_with_k_is_one_clear_error_without_a_contradicting_warning(tmp_path):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_k')
    try:
        proc = run_bridge(tmp_path, slcan_yaml(peer, '/**:\n  ros__parameters:\n'
                                                     '    devices: [ams]\n', bitrate='500k'))
    finally:
        peer.shutdown()
    assert proc.returncode == 2, proc.stderr
    assert "can.bitrate = '500k' must be a number: write 500000" in proc.stderr, proc.stderr
    assert 'WARN' not in proc.stderr and 'is 0 with slcan' not in proc.stderr, proc.stderr


@pytest.mark.parametrize('text, plain', [('500k', '500000'), ('1M', '1000000'),
                                         ('125 kbit/s', '125000'), ('2.5k', '2500')])
def test_a_number_with_k_or_m_is_written_out_in_the_error(text, plain):
    spec = next(spec for spec in BUS_PARAMS if spec.key == 'bitrate')
    with pytest.raises(ParamError, match=f'must be a number: write {plain} '):
        coerce('can.bitrate', spec, text)
    with pytest.raises(ParamError, match=r'must be a number$'):
        coerce('can.bitrate', spec, 'fast')


def test_a_stop_while_the_slcan_adapter_settles_is_prompt_and_sends_nothing(tmp_path):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_settle')
    io = CanIo(BusConfig(interface='slcan', channel=peer.channel, bitrate=500000,
                         options={'sleep_after_open': SETTLE}, reconnect_period=0.2),
               lambda *frame: None)
    try:
        io.start()
        time.sleep(0.5)  # the port is open, the adapter settling
        started = time.monotonic()
        stopper = threading.Thread(target=io.stop)
        stopper.start()
        stopper.join(timeout=SETTLE + 5.0)
        took = time.monotonic() - started
        fd = lock_serial_port(str(peer.channel))  # the port's lock was released
        assert fd is not None
        os.close(fd)
    finally:
        io.stop()
        peer.shutdown()
    assert took < SETTLE / 2, f'the stop waited {took:.1f} s for the adapter to settle'
    assert peer.commands == [], peer.commands  # neither the bit rate nor the open
