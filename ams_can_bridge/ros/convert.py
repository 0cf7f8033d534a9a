# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Device reports (plain dataclasses) -> ROS message objects.

The live telemetry and /diagnostics are serialized by ros/diag_cdr.py and published raw;
these message objects serve the 1 Hz stale messages (built once per device revision),
/clock, and every message when diag_cdr's start check fails.
"""
from __future__ import annotations

import functools
import logging
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray, MultiArrayDimension, MultiArrayLayout

from ams_can_bridge import reports
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport


def stamp_msg(stamp: float) -> Time:
    """builtin_interfaces/Time from seconds since the epoch (NaN/negative -> zero)."""
    sec, nanosec = reports.stamp_parts(stamp)
    return Time(sec=sec, nanosec=nanosec)


def battery_state(report: BatteryReport, frame_id: str,
                  fallback_stamp: float | None = None) -> BatteryState:
    """
    sensor_msgs/BatteryState from a BatteryReport (NaN stays NaN: unknown).

    The stamp is the time of the primary frame on the bus; fallback_stamp (now) is used
    when the device never sent one (stale messages before any frame).
    """
    fields = reports.battery_fields(report)
    # array('f') skips rclpy's per-element range check of float32[] lists (half the cost)
    fields['cell_voltage'] = reports.float32_array(fields['cell_voltage'])
    fields['cell_temperature'] = reports.float32_array(fields['cell_temperature'])
    msg = BatteryState(**fields)
    msg.header.stamp = stamp_msg(reports.report_stamp(report, fallback_stamp))
    msg.header.frame_id = frame_id
    return msg


def diagnostic_status(report: DiagnosticReport, name: str,
                      hardware_id: str) -> DiagnosticStatus:
    """diagnostic_msgs/DiagnosticStatus from a DiagnosticReport."""
    return DiagnosticStatus(
        level=bytes([int(report.level)]), name=name, message=report.message,
        hardware_id=hardware_id,
        values=[KeyValue(key=str(k), value=str(v)) for k, v in report.values.items()])


def multi_array(rows: int, cols: int, data: list[float],
                labels: tuple[str, str] = ('bank', 'sensor')) -> Float32MultiArray:
    """std_msgs/Float32MultiArray, row-major rows x cols, with its layout dims."""
    msg = Float32MultiArray()
    msg.layout = _layout(rows, cols, labels)
    msg.data = reports.float32_array(data)
    return msg


@functools.lru_cache(maxsize=64)
def _layout(rows: int, cols: int, labels: tuple[str, str]) -> MultiArrayLayout:
    # One layout object per shape, shared by every message of that shape (publishing only
    # reads it): building the dimension messages was much of a multi_array's cost.
    return MultiArrayLayout(dim=[MultiArrayDimension(label=label, size=size, stride=stride)
                                 for label, size, stride in reports.array_dims(rows, cols,
                                                                               labels)],
                            data_offset=0)


class RosLogHandler(logging.Handler):
    """Forward stdlib logging records (from CanIo) to the node's rclpy logger."""

    def __init__(self, ros_logger: Any) -> None:
        super().__init__()
        self.ros_logger = ros_logger

    def emit(self, record: logging.LogRecord) -> None:
        text = self.format(record)
        if record.levelno >= logging.ERROR:
            self.ros_logger.error(text)
        elif record.levelno >= logging.WARNING:
            self.ros_logger.warning(text)
        elif record.levelno >= logging.INFO:
            self.ros_logger.info(text)
        else:
            self.ros_logger.debug(text)


class ContextLog:
    """The node's logger while its context is up; silent once ROS is shut down (Ctrl-C)."""

    def __init__(self, ros_logger: Any, node: Any) -> None:
        """Log to ``ros_logger`` while ``node.context.ok()``."""
        self._log = ros_logger
        self._node = node

    def info(self, message: str, /) -> object:
        """Log at INFO."""
        return self._node.context.ok() and self._log.info(message)

    def warning(self, message: str, /) -> object:
        """Log at WARN."""
        return self._node.context.ok() and self._log.warning(message)

    def error(self, message: str, /) -> object:
        """Log at ERROR."""
        return self._node.context.ok() and self._log.error(message)


def stdlib_logger(name: str, ros_logger: Any, level: int = logging.NOTSET) -> logging.Logger:
    """Return the stdlib logger ``name`` whose records go to ``ros_logger`` only."""
    logger = logging.getLogger(name)
    logger.propagate = False
    # one handler, replaced: configured again (lifecycle), a logger is not printed twice
    logger.handlers = [RosLogHandler(ros_logger)]
    if level:  # DEBUG: the rclpy logger decides what is shown
        logger.setLevel(level)
    return logger
