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

from importlib.metadata import version
import struct
from typing import Any, Literal

from rosbags.rosbag2 import StoragePlugin, Writer

from ams_can_bridge import cdr, reports
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport
from ams_can_bridge.offline.bag_types import MSGDEFS

STORAGES = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
BATTERY_STATE = 'sensor_msgs/msg/BatteryState'
MULTI_ARRAY = 'std_msgs/msg/Float32MultiArray'
FLOAT32 = 'std_msgs/msg/Float32'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
BAG_VERSION: Literal[9] = 9  # rosbag2 metadata of Jazzy
# The rosbags releases whose McapWriter.write ``BagOut._write_mcap`` repeats (any other:
# rosbags' own write). Its ten calls a message were a tenth of a conversion's loop
# (bench/README.md, third pass); test_log2bag_golden.py holds the files byte-identical.
MCAP_WRITE_KNOWN = ('0.11.9',)
# an MCAP Message record: opcode 0x05, record length, channel id, sequence 0, log and
# publish time (both the bag time), then the data
_MCAP_MESSAGE = struct.Struct('<BQHIQQ').pack
_MCAP_MESSAGE_FIELDS = 22  # the record's bytes before the data
_MCAP_CHUNK_SIZE = 2 ** 20  # rosbags closes a chunk past this many bytes


class BagOut:
    """Topics of one bag: open, write messages at their log time, close."""

    def __init__(self, path: str, storage: str = 'mcap') -> None:
        """Create the bag directory (it must not exist yet, rosbag2's rule)."""
        self.writer = Writer(path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
        self.writer.open()
        storage_writer = getattr(self.writer, 'storage', None)
        own_write = (storage == 'mcap' and version('rosbags') in MCAP_WRITE_KNOWN
                     and type(storage_writer).__name__ == 'McapWriter')
        self._mcap: Any = storage_writer if own_write else None
        self._connections: dict[str, Any] = {}
        self._diagnostics = cdr.DiagnosticsEncoder()
        self._arrays = cdr.ArrayEncoder()
        self.counts: dict[str, int] = {}

    def _write(self, topic: str, msgtype: str, raw: bytes, sec: int, nanosec: int) -> None:
        connection = self._connections.get(topic)
        if connection is None:
            msgdef, rihs01 = MSGDEFS[msgtype]  # Jazzy's (bag_types.py)
            connection = self.writer.add_connection(topic, msgtype, msgdef=msgdef, rihs01=rihs01)
            self._connections[topic] = connection
            self.counts[topic] = 0
        stamp = sec * 1_000_000_000 + nanosec
        mcap = self._mcap
        if mcap is None:
            self.writer.write(connection, stamp, raw)
        else:
            self._write_mcap(mcap, connection.id, stamp, raw)
        self.counts[topic] += 1

    def _write_mcap(self, mcap: Any, cid: int, stamp: int, raw: bytes) -> None:
        """Do what rosbags' Writer.write and McapWriter.write do (its span: at close)."""
        if stamp < mcap.message_start_time:
            mcap.message_start_time = stamp
        if stamp > mcap.message_end_time:
            mcap.message_end_time = stamp
        mcap.channel_stats[cid] += 1
        chunk = mcap.chunk
        if stamp < chunk.message_start_time:
            chunk.message_start_time = stamp
        if stamp > chunk.message_end_time:
            chunk.message_end_time = stamp
        bio = chunk.bio
        chunk.msgs[cid].append((stamp, bio.tell()))
        bio.write(_MCAP_MESSAGE(0x05, _MCAP_MESSAGE_FIELDS + len(raw), cid, 0, stamp, stamp))
        bio.write(raw)
        self.writer.counts[cid] += 1
        if bio.tell() > _MCAP_CHUNK_SIZE:
            mcap.close_chunk()

    def battery_state(self, topic: str, report: BatteryReport, frame_id: str,
                      stamp: float) -> None:
        """Write one BatteryState, header stamp and bag time = stamp."""
        sec, nanosec = reports.stamp_parts(stamp)
        self._write(topic, BATTERY_STATE, cdr.battery_state_at(report, frame_id, sec, nanosec),
                    sec, nanosec)

    def multi_array(self, topic: str, rows: int, cols: int, data: list[float],
                    stamp: float) -> None:
        """Write one Float32MultiArray (row-major rows x cols) at bag time stamp."""
        self._write(topic, MULTI_ARRAY, self._arrays.encode(topic, rows, cols, data),
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
        mcap = self._mcap
        if mcap is not None:  # the span Writer.write would have kept: the storage's
            writer = self.writer
            writer.min_timestamp = min(writer.min_timestamp, mcap.message_start_time)
            writer.max_timestamp = max(writer.max_timestamp, mcap.message_end_time)
        self.writer.close()
