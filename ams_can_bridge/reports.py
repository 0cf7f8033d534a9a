# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Device reports -> the fields of ROS messages, without ROS.

``ros/convert.py`` fills rclpy messages from these and ``log2bag`` fills rosbags messages
from the same, so a bag written offline holds exactly what the live bridge publishes.
"""
from __future__ import annotations

from array import array
import math
from typing import Any, Iterable

from ams_can_bridge.bus_state import BusState
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport, Level


def stamp_parts(stamp: float) -> tuple[int, int]:
    """Return (sec, nanosec) of seconds since the epoch (NaN/negative -> (0, 0))."""
    if not math.isfinite(stamp) or stamp < 0:
        return 0, 0
    sec = int(stamp)
    nanosec = int(round((stamp - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return sec, nanosec


def report_stamp(report: BatteryReport, fallback: float | None = None) -> float:
    """Return the stamp of a report: its primary frame's time, else fallback (or NaN)."""
    if not math.isfinite(report.stamp) and fallback is not None:
        return fallback
    return report.stamp


F32_NEGATIVE_ZERO = array('f', [-0.0]).tobytes()


def float32_array(values: Iterable[float]) -> array:
    """
    Return values as array('f'), every -0.0 made 0.0 (NaN stays NaN).

    A sign flip or a negative scale turns a reading of 0 into -0.0, which a plot or a log
    shows as "-0.0": the same quantity, but it reads like a tiny discharge. The scan for
    the float32 bit pattern runs in C; only an array that has one is rebuilt.
    """
    out = array('f', values)
    if F32_NEGATIVE_ZERO in out.tobytes():  # a hit off the 4-byte grid only costs a rebuild
        out = array('f', [v + 0.0 for v in out])  # -0.0 + 0.0 == 0.0
    return out


def battery_fields(report: BatteryReport) -> dict[str, Any]:
    """Return the sensor_msgs/BatteryState fields of a report, header excepted (-0.0 -> 0.0)."""
    return {
        # + 0.0: -0.0 becomes 0.0 (IEEE 754), NaN and every other value stay as they are
        'voltage': float(report.voltage) + 0.0,
        'temperature': float(report.temperature) + 0.0,
        'current': float(report.current) + 0.0,
        'charge': float(report.charge) + 0.0,
        'capacity': float(report.capacity) + 0.0,
        'design_capacity': float(report.design_capacity) + 0.0,
        'percentage': float(report.percentage) + 0.0,
        'power_supply_status': int(report.power_supply_status),
        'power_supply_health': int(report.power_supply_health),
        'power_supply_technology': int(report.power_supply_technology),
        'present': bool(report.present),
        # As the device holds them (floats): each writer packs them as float32 its own way.
        'cell_voltage': report.cell_voltage,
        'cell_temperature': report.cell_temperature,
        'location': report.location,
        'serial_number': report.serial_number,
    }


def array_dims(rows: int, cols: int,
               labels: tuple[str, str] = ('bank', 'sensor')) -> list[tuple[str, int, int]]:
    """Return the (label, size, stride) of a row-major rows x cols Float32MultiArray."""
    return [(labels[0], rows, rows * cols), (labels[1], cols, cols)]


_BUS_LEVELS = {
    BusState.CONNECTED: Level.OK,
    BusState.ERROR_PASSIVE: Level.WARN,
    BusState.CONNECTING: Level.WARN,  # the first attempt is still under way
    BusState.REPLAY_FINISHED: Level.OK,  # a replay that reached the end of its file
}


# s a frame the bridge could not send keeps a connected bus at WARN (a heartbeat, a command)
DROPPED_TX_WARN_PERIOD = 10.0


def _dropped_lately(status: Any) -> bool:
    ago = getattr(status, 'dropped_tx_ago', None)
    return ago is not None and ago < DROPPED_TX_WARN_PERIOD


def bus_level(status: Any) -> Level:
    """Return the level bus_report() gives a BusStatus, without building the report."""
    level = _BUS_LEVELS.get(status.state, Level.ERROR)  # a BusState is its own text
    if level == Level.OK and _dropped_lately(status):
        return Level.WARN
    if level == Level.OK and getattr(status, 'garbage_recent', False):
        return Level.WARN  # frames flow, but the adapter also sends what is no line
    return level


def bus_report(status: Any, malformed: int, interface: str) -> DiagnosticReport:
    """
    Build the CAN bus DiagnosticReport from a CanIo BusStatus and the devices' counters.

    OK when connected (or a replay that finished), WARN on error-passive or while a frame to
    send was dropped in the last DROPPED_TX_WARN_PERIOD s, ERROR otherwise (error, bus-off,
    reconnecting, cannot open) with the reason in the message.
    """
    state = BusState(status.state)
    level = bus_level(status)
    reason = str(status.reason or '')
    message = state + (f': {reason}' if reason and _BUS_LEVELS.get(state) != Level.OK else '')
    down_for = getattr(status, 'down_for', None)
    if down_for is not None:
        message += f' (down for {down_for:.1f} s)'
    if _dropped_lately(status) and state in (BusState.CONNECTED, BusState.ERROR_PASSIVE):
        message += (f'; {status.frames_dropped_tx} frames dropped (tx), the last '
                    f'{status.dropped_tx_ago:.1f} s ago: {status.dropped_tx_reason}')
    garbage = getattr(status, 'garbage_bytes', 0)
    if getattr(status, 'garbage_recent', False):
        message += (f': the adapter sends bytes without a line end ({garbage} dropped so far):'
                    ' check its serial settings (baud rate) and firmware')
    values = {
        'state': str(state),
        'reason': reason,
        'frames in': str(status.frames_in),
        'frames out': str(status.frames_out),
        'frames dropped (tx)': str(getattr(status, 'frames_dropped_tx', 0)),
        'last dropped (tx)': str(getattr(status, 'dropped_tx_reason', '') or ''),
        'malformed frames': str(malformed),
        'error frames': str(status.error_frames),
        'reconnects': str(status.reconnects),
        'frame handler errors': str(getattr(status, 'callback_errors', 0)),
        'unreadable frames': str(getattr(status, 'frames_unreadable', 0)),
        'garbage bytes dropped': str(garbage),
        'adapter': str(getattr(status, 'hardware_id', '') or ''),
        'replay': (('finished' if state == BusState.REPLAY_FINISHED else 'playing')
                   if interface == 'replay' else 'off'),
    }
    if down_for is not None:
        values['outage s'] = f'{down_for:.1f}'
    last_outage = getattr(status, 'last_outage', None)
    if last_outage is not None:
        values['last outage s'] = f'{last_outage:.1f}'
    return DiagnosticReport(level, message, values)
