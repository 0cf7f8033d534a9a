# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
/diagnostics, BatteryState and the arrays serialized by the bridge itself: CDR, published raw.

The bytes are built ROS-free in ``ams_can_bridge/cdr.py`` (log2bag writes the same into its
bags); this module checks them against rclpy's serialization at start.

Every second the bridge publishes ~340 key/value pairs. Through rclpy that costs two
passes over Python objects: building a KeyValue per pair, then rclpy converting each back
into C strings to serialize them (far more than the DDS write of the result:
bench/README.md). About three quarters of the pairs are unchanged from one second to the next,
so this encoder keeps the serialized bytes of each (status, key) with its value and joins
them, re-encoding only what changed.

The layout is the XCDR1 little-endian encoding of diagnostic_msgs/DiagnosticArray (what
``rclpy.serialization.serialize_message`` gives): a 4-byte encapsulation header, then each
field aligned to its size counted from the end of that header; a string is a uint32 length
(with the NUL), its UTF-8 bytes and a NUL. ``DiagnosticsEncoder.check()`` compares the
encoder with rclpy's serialization once at start; should they ever differ (another rmw,
another encoding), the node publishes the message objects as before.

The same holds, for the same reason, for each primary frame's BatteryState and arrays
(``battery_state``, ``multi_array``; ``check_telemetry()``): rclpy's conversion of the
message objects was most of a publish and most of the code a cold publish runs.
"""
from __future__ import annotations

import math
from typing import Any, Iterable

from rclpy.serialization import deserialize_message, serialize_message

from diagnostic_msgs.msg import DiagnosticArray

from ams_can_bridge import cdr, reports
from ams_can_bridge.cdr import cdr_string, float32, multi_array  # noqa: F401 (this module's API)
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport, Level


class DiagnosticsEncoder(cdr.DiagnosticsEncoder):
    """``cdr.DiagnosticsEncoder`` with its check against rclpy's serialization."""

    def check(self) -> bool:
        """Tell whether rclpy reads this encoder's bytes as the message they stand for."""
        from ams_can_bridge.ros.convert import diagnostic_status, stamp_msg
        sample = [('bridge: a', DiagnosticReport(Level.WARN, 'odd length msg', {
                       'k': 'v', 'key 2': '', 'ключ': 'значение', 'long key': 'x' * 13})),
                  ('b', DiagnosticReport(Level.OK, '', {})),
                  ('bridge: CAN bus', DiagnosticReport(Level.ERROR, 'abc', {'n': '1'}))]
        for stamp in (1_700_000_000.123456789, float('nan')):
            expected = DiagnosticArray()
            expected.header.stamp = stamp_msg(stamp)
            expected.status = [diagnostic_status(r, n, 'hw:x') for n, r in sample]
            try:
                got = deserialize_message(self.encode(stamp, sample, 'hw:x'), DiagnosticArray)
            except Exception:
                return False
            if got != expected:
                return False
        self._pairs.clear()
        return True


def diagnostic_array(stamp: float, statuses: Iterable[tuple[str, Any]],
                     hardware_id: str) -> DiagnosticArray:
    """Build the DiagnosticArray message object (the path when the encoder is not used)."""
    from ams_can_bridge.ros.convert import diagnostic_status, stamp_msg
    msg = DiagnosticArray()
    msg.header.stamp = stamp_msg(stamp)
    msg.status = [diagnostic_status(report, name, hardware_id) for name, report in statuses]
    return msg


def battery_state(report: BatteryReport, frame_id: str,
                  fallback_stamp: float | None = None) -> bytes:
    """Serialize the BatteryState convert builds from the same report, as rclpy would."""
    sec, nanosec = reports.stamp_parts(reports.report_stamp(report, fallback_stamp))
    return cdr.battery_state_at(report, frame_id, sec, nanosec)


def restamp(message: bytes, stamp: float) -> bytes:
    """Return a serialized BatteryState (or any message a Header starts) stamped ``stamp``."""
    return cdr.restamp(message, *reports.stamp_parts(stamp))


def _same(raw: bytes, msg: Any) -> bool:
    """Tell whether a subscriber reads the bytes as it reads the message (NaN == NaN)."""
    kind = type(msg)
    return (repr(deserialize_message(raw, kind))
            == repr(deserialize_message(serialize_message(msg), kind)))


def check_telemetry() -> bool:
    """Tell whether rclpy reads battery_state() (restamped too), multi_array(), float32() right."""
    from std_msgs.msg import Float32

    from ams_can_bridge.ros import convert
    nan = math.nan
    samples = [
        BatteryReport(),
        BatteryReport(stamp=1_700_000_000.123456789, voltage=403.2, temperature=31.5,
                      current=-12.25, charge=55.5, capacity=60.0, design_capacity=62.0,
                      percentage=0.925, power_supply_status=2, power_supply_health=1,
                      power_supply_technology=2, present=True, cell_voltage=[3.6, nan, 1e39],
                      cell_temperature=[25.0], location='rück', serial_number='S/N 7'),
        BatteryReport(stamp=5.999999999, cell_voltage=[1.0] * 3, location='abc'),
    ]
    try:
        for frame_id in ('', 'ab', 'abc', 'pack_link'):
            for report in samples:
                if not _same(battery_state(report, frame_id, 2.5),
                             convert.battery_state(report, frame_id, 2.5)):
                    return False
                # a stale message: built once, restamped every second
                msg = convert.battery_state(report, frame_id, 2.5)
                msg.header.stamp = convert.stamp_msg(1_700_000_001.75)
                if not _same(restamp(battery_state(report, frame_id, 2.5), 1_700_000_001.75),
                             msg):
                    return False
        for rows, cols, labels in ((2, 3, ('bank', 'sensor')), (1, 5, ('module', 'cell'))):
            data = [float(k) for k in range(rows * cols - 1)] + [nan]
            if not _same(multi_array(rows, cols, data, labels),
                         convert.multi_array(rows, cols, data, labels)):
                return False
        for value in (0.0, -12.25, 9000.5, nan, math.inf):  # a pack's figures
            if not _same(float32(value), Float32(data=value)):
                return False
    except Exception:
        return False
    return True
