"""Device reports (plain dataclasses) -> ROS messages."""
from __future__ import annotations

from array import array
import functools
import logging
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray, Header, MultiArrayDimension, MultiArrayLayout

from ams_can_bridge import reports
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport
from ams_can_bridge.reports import bus_report  # noqa: F401 (re-exported)


# Fast construction. The bridge builds a BatteryState per primary frame and ~340 KeyValues a
# second; a generated message's __init__ (kwargs, a property setter per field, a default
# Header and Time built only to be replaced) cost more than filling its slots, which is all
# publishing reads. So the messages are built with object.__new__ and their slots filled,
# the same values as the constructor would store (test_convert.py compares the serialized
# bytes). ROS_PYTHON_CHECK_FIELDS=1 (the generated classes then check every field) keeps the
# constructors, checks included.
_new = object.__new__
_FAST = not KeyValue()._check_fields


def _time(sec: int, nanosec: int) -> Time:
    msg = _new(Time)
    msg._check_fields = False
    msg._sec = sec
    msg._nanosec = nanosec
    return msg


def stamp_msg(stamp: float) -> Time:
    """builtin_interfaces/Time from seconds since the epoch (NaN/negative -> zero)."""
    sec, nanosec = reports.stamp_parts(stamp)
    if _FAST:
        return _time(sec, nanosec)
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
    fields['cell_voltage'] = array('f', fields['cell_voltage'])
    fields['cell_temperature'] = array('f', fields['cell_temperature'])
    stamp = stamp_msg(reports.report_stamp(report, fallback_stamp))
    if not _FAST:
        msg = BatteryState(**fields)
        msg.header.stamp = stamp
        msg.header.frame_id = frame_id
        return msg
    header = _new(Header)
    header._check_fields = False
    header._stamp = stamp
    header._frame_id = frame_id
    msg = _new(BatteryState)
    msg._check_fields = False
    msg._header = header
    msg._voltage = fields['voltage']
    msg._temperature = fields['temperature']
    msg._current = fields['current']
    msg._charge = fields['charge']
    msg._capacity = fields['capacity']
    msg._design_capacity = fields['design_capacity']
    msg._percentage = fields['percentage']
    msg._power_supply_status = fields['power_supply_status']
    msg._power_supply_health = fields['power_supply_health']
    msg._power_supply_technology = fields['power_supply_technology']
    msg._present = fields['present']
    msg._cell_voltage = fields['cell_voltage']
    msg._cell_temperature = fields['cell_temperature']
    msg._location = fields['location']
    msg._serial_number = fields['serial_number']
    return msg


def key_value(key: str, value: str) -> KeyValue:
    """diagnostic_msgs/KeyValue of two strings."""
    if not _FAST:
        return KeyValue(key=key, value=value)
    msg = _new(KeyValue)
    msg._check_fields = False
    msg._key = key
    msg._value = value
    return msg


def diagnostic_status(report: DiagnosticReport, name: str,
                      hardware_id: str) -> DiagnosticStatus:
    """diagnostic_msgs/DiagnosticStatus from a DiagnosticReport."""
    return DiagnosticStatus(
        level=bytes([int(report.level)]), name=name, message=report.message,
        hardware_id=hardware_id,
        values=[key_value(str(k), str(v)) for k, v in report.values.items()])


def multi_array(rows: int, cols: int, data: list[float],
                labels: tuple[str, str] = ('bank', 'sensor')) -> Float32MultiArray:
    """std_msgs/Float32MultiArray, row-major rows x cols, with its layout dims."""
    if not _FAST:
        msg = Float32MultiArray()
        msg.layout = _layout(rows, cols, labels)
        msg.data = array('f', data)
        return msg
    msg = _new(Float32MultiArray)
    msg._check_fields = False
    msg._layout = _layout(rows, cols, labels)
    msg._data = array('f', data)
    return msg


@functools.lru_cache(maxsize=64)
def _layout(rows: int, cols: int, labels: tuple[str, str]) -> MultiArrayLayout:
    # One layout object per shape, shared by every message of that shape (publishing only
    # reads it): building the dimension messages was a third of a multi_array's cost.
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


def format_ids(ids: frozenset[int] | set[int], extended: bool) -> str:
    """'0x300-0x301, 0x305' (runs of consecutive IDs collapsed), '(29-bit)' when extended."""
    runs: list[list[int]] = []
    for i in sorted(ids):
        if runs and i == runs[-1][1] + 1:
            runs[-1][1] = i
        else:
            runs.append([i, i])
    text = ', '.join(f'0x{a:X}' if a == b else f'0x{a:X}-0x{b:X}' for a, b in runs)
    return text + (' (29-bit)' if extended else '')
