"""Device reports (plain dataclasses) -> ROS messages."""
from __future__ import annotations

import logging
import math
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray, MultiArrayDimension

from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport, Level


def stamp_msg(wall_time: float) -> Time:
    """builtin_interfaces/Time from seconds since the epoch (NaN/negative -> zero)."""
    if not math.isfinite(wall_time) or wall_time < 0:
        return Time()
    sec = int(wall_time)
    nanosec = int(round((wall_time - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return Time(sec=sec, nanosec=nanosec)


def battery_state(report: BatteryReport, frame_id: str,
                  fallback_stamp: float | None = None) -> BatteryState:
    """
    sensor_msgs/BatteryState from a BatteryReport (NaN stays NaN: unknown).

    The stamp is the receive time of the primary frame; fallback_stamp (now) is used when
    the device never sent one (stale messages before any frame).
    """
    msg = BatteryState()
    stamp = report.stamp
    if not math.isfinite(stamp) and fallback_stamp is not None:
        stamp = fallback_stamp
    msg.header.stamp = stamp_msg(stamp)
    msg.header.frame_id = frame_id
    msg.voltage = float(report.voltage)
    msg.temperature = float(report.temperature)
    msg.current = float(report.current)
    msg.charge = float(report.charge)
    msg.capacity = float(report.capacity)
    msg.design_capacity = float(report.design_capacity)
    msg.percentage = float(report.percentage)
    msg.power_supply_status = int(report.power_supply_status)
    msg.power_supply_health = int(report.power_supply_health)
    msg.power_supply_technology = int(report.power_supply_technology)
    msg.present = bool(report.present)
    msg.cell_voltage = [float(v) for v in report.cell_voltage]
    msg.cell_temperature = [float(v) for v in report.cell_temperature]
    msg.location = report.location
    msg.serial_number = report.serial_number
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
    msg.layout.dim = [
        MultiArrayDimension(label=labels[0], size=rows, stride=rows * cols),
        MultiArrayDimension(label=labels[1], size=cols, stride=cols),
    ]
    msg.layout.data_offset = 0
    msg.data = [float(v) for v in data]
    return msg


_BUS_LEVELS = {
    'connected': Level.OK,
    'error-passive': Level.WARN,
    'connecting': Level.WARN,  # the first attempt is still under way
    'replay finished': Level.OK,  # a replay that reached the end of its file
}


def bus_report(status: Any, malformed: int, interface: str) -> DiagnosticReport:
    """
    Build the CAN bus DiagnosticReport from a CanIo BusStatus and the devices' counters.

    OK when connected (or a replay that finished), WARN on error-passive, ERROR otherwise
    (error, bus-off, reconnecting, cannot open) with the reason in the message.
    """
    state = str(status.state)
    level = _BUS_LEVELS.get(state, Level.ERROR)
    reason = str(status.reason or '')
    message = state + (f': {reason}' if reason and level != Level.OK else '')
    values = {
        'state': state,
        'reason': reason,
        'frames in': str(status.frames_in),
        'frames out': str(status.frames_out),
        'frames dropped (tx)': str(getattr(status, 'frames_dropped_tx', 0)),
        'malformed frames': str(malformed),
        'error frames': str(status.error_frames),
        'reconnects': str(status.reconnects),
        'adapter': str(getattr(status, 'hardware_id', '') or ''),
        'replay': (('finished' if state == 'replay finished' else 'playing')
                   if interface == 'replay' else 'off'),
    }
    return DiagnosticReport(level, message, values)


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
