"""
A rosbag2 directory written with the ``rosbags`` library: no ROS install, no DDS.

Messages are built from the same report fields as the live bridge's (``reports``), as the
rosbags Jazzy type store defines them, and serialized to CDR as rclpy would.
"""
from __future__ import annotations

from typing import Any, Literal

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

from ams_can_bridge import reports
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
        self.store = get_typestore(Stores.ROS2_JAZZY)
        t = self.store.types
        self._time, self._header = t['builtin_interfaces/msg/Time'], t['std_msgs/msg/Header']
        self._battery = t[BATTERY_STATE]
        self._array, self._dim = t[MULTI_ARRAY], t['std_msgs/msg/MultiArrayDimension']
        self._layout = t['std_msgs/msg/MultiArrayLayout']
        self._diag_array = t[DIAGNOSTIC_ARRAY]
        self._float32 = t[FLOAT32]
        self._status = t['diagnostic_msgs/msg/DiagnosticStatus']
        self._key_value = t['diagnostic_msgs/msg/KeyValue']
        self.writer = Writer(path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
        self.writer.open()
        self._connections: dict[str, Any] = {}
        self.counts: dict[str, int] = {}

    def _write(self, topic: str, msgtype: str, msg: Any, stamp: float) -> None:
        connection = self._connections.get(topic)
        if connection is None:
            connection = self.writer.add_connection(topic, msgtype, typestore=self.store)
            self._connections[topic] = connection
            self.counts[topic] = 0
        sec, nanosec = reports.stamp_parts(stamp)
        self.writer.write(connection, sec * 1_000_000_000 + nanosec,
                          self.store.serialize_cdr(msg, msgtype))
        self.counts[topic] += 1

    def _stamp(self, stamp: float) -> Any:
        return self._time(*reports.stamp_parts(stamp))

    def battery_state(self, topic: str, report: BatteryReport, frame_id: str,
                      stamp: float) -> None:
        """Write one BatteryState, header stamp and bag time = stamp."""
        fields = reports.battery_fields(report)
        for key in ('cell_voltage', 'cell_temperature'):
            fields[key] = np.frombuffer(reports.float32_array(fields[key]), np.float32)
        msg = self._battery(header=self._header(self._stamp(stamp), frame_id), **fields)
        self._write(topic, BATTERY_STATE, msg, stamp)

    def multi_array(self, topic: str, rows: int, cols: int, data: list[float],
                    stamp: float) -> None:
        """Write one Float32MultiArray (row-major rows x cols) at bag time stamp."""
        dims = [self._dim(label, size, stride)
                for label, size, stride in reports.array_dims(rows, cols)]
        msg = self._array(self._layout(dims, 0),
                          np.frombuffer(reports.float32_array(data), np.float32))
        self._write(topic, MULTI_ARRAY, msg, stamp)

    def float32(self, topic: str, value: float, stamp: float) -> None:
        """Write one std_msgs/Float32 at bag time stamp."""
        self._write(topic, FLOAT32, self._float32(float(value)), stamp)

    def diagnostics(self, statuses: list[tuple[str, DiagnosticReport]], hardware_id: str,
                    stamp: float) -> None:
        """Write one DiagnosticArray of (status name, report) at stamp."""
        status = [self._status(int(report.level), name, report.message, hardware_id,
                               [self._key_value(str(k), str(v))
                                for k, v in report.values.items()])
                  for name, report in statuses]
        msg = self._diag_array(self._header(self._stamp(stamp), ''), status)
        self._write('/diagnostics', DIAGNOSTIC_ARRAY, msg, stamp)

    def close(self) -> None:
        """Finish the bag (metadata.yaml is written here)."""
        self.writer.close()
