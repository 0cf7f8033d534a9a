# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A rosbag2 directory written with the ``rosbags`` library: no ROS install, no DDS.

Messages are serialized from the same report fields as the live bridge's by the project's
own CDR encoder (``cdr.py``, the bytes rclpy gives), cheaper than rosbags' message objects
and their serializer. rosbags writes the bag and gives each
topic its Jazzy message definition.
"""
from __future__ import annotations

from typing import Any, Literal

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

from ams_can_bridge import cdr, reports
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport

STORAGES = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
BATTERY_STATE = 'sensor_msgs/msg/BatteryState'
MULTI_ARRAY = 'std_msgs/msg/Float32MultiArray'
FLOAT32 = 'std_msgs/msg/Float32'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
BAG_VERSION: Literal[9] = 9  # rosbag2 metadata of Jazzy


class BagOut:
    """Topics of one bag: open, write messages at their log time, close."""

    def __init__(self, path: str, storage: str = 'mcap') -> None:
        """Create the bag directory (it must not exist yet, rosbag2's rule)."""
        self.store = get_typestore(Stores.ROS2_JAZZY)  # the connections' message definitions
        self.writer = Writer(path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
        self.writer.open()
        self._connections: dict[str, Any] = {}
        self._diagnostics = cdr.DiagnosticsEncoder()
        self.counts: dict[str, int] = {}

    def _write(self, topic: str, msgtype: str, raw: bytes, sec: int, nanosec: int) -> None:
        connection = self._connections.get(topic)
        if connection is None:
            connection = self.writer.add_connection(topic, msgtype, typestore=self.store)
            self._connections[topic] = connection
            self.counts[topic] = 0
        self.writer.write(connection, sec * 1_000_000_000 + nanosec, raw)
        self.counts[topic] += 1

    def battery_state(self, topic: str, report: BatteryReport, frame_id: str,
                      stamp: float) -> None:
        """Write one BatteryState, header stamp and bag time = stamp."""
        sec, nanosec = reports.stamp_parts(stamp)
        self._write(topic, BATTERY_STATE, cdr.battery_state_at(report, frame_id, sec, nanosec),
                    sec, nanosec)

    def multi_array(self, topic: str, rows: int, cols: int, data: list[float],
                    stamp: float) -> None:
        """Write one Float32MultiArray (row-major rows x cols) at bag time stamp."""
        self._write(topic, MULTI_ARRAY, cdr.multi_array(rows, cols, data),
                    *reports.stamp_parts(stamp))

    def float32(self, topic: str, value: float, stamp: float) -> None:
        """Write one std_msgs/Float32 at bag time stamp."""
        self._write(topic, FLOAT32, cdr.float32(value), *reports.stamp_parts(stamp))

    def diagnostics(self, statuses: list[tuple[str, DiagnosticReport]], hardware_id: str,
                    stamp: float) -> None:
        """Write one DiagnosticArray of (status name, report) at stamp."""
        raw = self._diagnostics.encode(stamp, statuses, hardware_id)
        self._write('/diagnostics', DIAGNOSTIC_ARRAY, raw, *reports.stamp_parts(stamp))

    def close(self) -> None:
        """Finish the bag (metadata.yaml is written here)."""
        self.writer.close()
