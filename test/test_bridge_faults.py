# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge under faults: missing adapter, unplugged adapter, malformed frames, silent device.

The adapter is a real slcan peer on a pty (python-can's real slcan driver on the bridge
side); malformed / silent devices use the virtual bus. Nothing may print a traceback.
"""
from __future__ import annotations

import math
import time

from sensor_msgs.msg import BatteryState
from bridge_runs import slcan_params
from slcan_peer import SlcanPeer
from shared import bms16_status, level, values

from ams_can_bridge.protocols.common import Frame

ERROR, STALE = 2, 3


def test_missing_adapter_then_plugged_in(rig_factory, tmp_path, capfd):
    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN0', plugged=False)
    try:
        h = rig_factory(slcan_params(peer), wait_connected=False)
        status = h.status('CAN bus', lambda s: level(s) == ERROR)
        assert values(status)['state'] == 'error'
        assert values(status)['reason']
        assert values(status)['reason'] in status.message
        peer.reopen()  # plug the adapter in: the node recovers alone
        status = h.status('CAN bus', lambda s: values(s)['state'] == 'connected')
        assert level(status) == 0
        peer.wait_open()
    finally:
        peer.shutdown()
    assert 'Traceback' not in capfd.readouterr().err


def test_adapter_unplugged_while_running_reconnects(rig_factory, tmp_path, capfd):
    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN1')
    try:
        h = rig_factory(dict(slcan_params(peer), devices=['bms16']),
                        topics={'bms16/battery_state': BatteryState}, wait_connected=False)
        h.status('CAN bus', lambda s: values(s)['state'] == 'connected')
        peer.wait_open()
        peer.close()  # unplugged: the /dev/serial/by-id style symlink disappears too
        assert not (tmp_path / 'ttyCAN1').exists()
        status = h.status('CAN bus', lambda s: values(s)['state'] == 'reconnecting')
        assert level(status) == ERROR
        assert values(status)['reason'] and values(status)['reason'] in status.message
        # how long the outage lasts, counting up while it lasts
        status = h.status('CAN bus', lambda s: float(values(s).get('outage s', 0)) >= 0.6)
        assert level(status) == ERROR and ' s)' in status.message
        assert 'down for' in status.message, status.message
        peer.reopen()  # plugged back in at the same path
        status = h.status('CAN bus', lambda s: values(s)['state'] == 'connected'
                          and int(values(s)['reconnects']) >= 1)
        assert level(status) == 0
        assert 'outage s' not in values(status) and 'down for' not in status.message
        assert float(values(status)['last outage s']) >= 0.6
        peer.wait_open()
        # data flows again through the new connection
        h.wait(lambda: peer.send(Frame(500, bms16_status(0, 55, 500, 0, 20)))
               and any(m.present and abs(m.percentage - 0.55) < 1e-6
                       for m in h.messages('bms16/battery_state')))
    finally:
        peer.shutdown()
    assert 'Traceback' not in capfd.readouterr().err


def test_a_garbled_slcan_line_is_a_dropped_frame_not_a_lost_bus(rig_factory, tmp_path, capfd):
    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN2')
    try:
        h = rig_factory(dict(slcan_params(peer), devices=['bms16']),
                        topics={'bms16/battery_state': BatteryState}, wait_connected=False)
        h.status('CAN bus', lambda s: values(s)['state'] == 'connected')
        peer.wait_open()
        # line noise: python-can's slcan driver raises on a line it cannot parse
        assert peer.send_raw(b't1F47' + b'ZZ' * 7 + b'\r')
        assert peer.send_raw(b'T\r')
        h.wait(lambda: peer.send(Frame(500, bms16_status(0, 44, 500, 0, 20)))
               and any(m.present and abs(m.percentage - 0.44) < 1e-6
                       for m in h.messages('bms16/battery_state')))
        status = h.status('CAN bus', lambda s: values(s)['unreadable frames'] == '2')
        assert values(status)['state'] == 'connected' and level(status) == 0
        assert values(status)['reconnects'] == '0'
    finally:
        peer.shutdown()
    err = capfd.readouterr().err
    assert 'unreadable message from the driver dropped' in err and 'Traceback' not in err


def test_malformed_frames_counted_never_published(rig_factory, capfd):
    h = rig_factory({'devices': ['bms16'], 'diagnostics_period': 0.2},
                    topics={'bms16/battery_state': BatteryState})
    for _ in range(3):
        h.send(500, bytes([0, 99, 1]))  # DLC 3 instead of 7
    status = h.status('CAN bus', lambda s: values(s)['malformed frames'] == '3')
    assert level(status) == 0
    device = h.status('bms16', lambda s: values(s).get('frames malformed') == '3')
    assert 'DLC 3' in values(device)['last malformed frame']
    assert not any(m.present for m in h.messages('bms16/battery_state'))
    # the node is alive and still decodes good frames
    h.send(500, bms16_status(0, 42, 480, 0, 21))
    msg = h.last('bms16/battery_state', lambda m: m.present)
    assert abs(msg.percentage - 0.42) < 1e-6
    h.wait(lambda: 'malformed frame' in capfd.readouterr().err, timeout=5)
    # the malformed log is throttled: more bad frames within 5 s add no log line
    for _ in range(5):
        h.send(500, bytes([0]))
    h.status('CAN bus', lambda s: values(s)['malformed frames'] == '8')
    end = time.monotonic() + 1.0  # several watch periods
    h.wait(lambda: time.monotonic() > end)
    assert 'malformed frame' not in capfd.readouterr().err


def test_silent_device_goes_stale_and_comes_back(rig_factory, capfd):
    h = rig_factory({'devices': ['bms16'], 'bms16.stale_timeout': 0.5,
                     'diagnostics_period': 0.2},
                    topics={'bms16/battery_state': BatteryState})
    h.send(500, bms16_status(0, 70, 510, 0, 22))
    h.last('bms16/battery_state', lambda m: m.present)
    h.status('bms16', lambda s: level(s) == 0)
    status = h.status('bms16', lambda s: level(s) == STALE)
    assert 'stale' in status.message
    # present:false at about 1 Hz while stale
    first = len(h.messages('bms16/battery_state'))
    h.wait(lambda: len(h.messages('bms16/battery_state')) >= first + 2, timeout=6)
    late = h.messages('bms16/battery_state')[first:]
    assert late and not any(m.present for m in late)
    # no stale numbers: a silent device's messages carry NaN, not its last values
    assert all(math.isnan(m.voltage) and math.isnan(m.current) and math.isnan(m.percentage)
               and all(math.isnan(v) for v in m.cell_voltage) for m in late)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in late]
    assert stamps == sorted(stamps)
    h.send(500, bms16_status(0, 71, 510, 0, 22))
    msg = h.last('bms16/battery_state', lambda m: m.present and m.percentage > 0.705)
    assert msg.present
    h.status('bms16', lambda s: level(s) == 0)
    err = [capfd.readouterr().err]
    h.wait(lambda: err.append(capfd.readouterr().err) or 'receiving again' in ''.join(err))
    assert 'STALE' in ''.join(err)
    assert 'Traceback' not in ''.join(err)
