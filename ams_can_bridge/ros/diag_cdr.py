"""
/diagnostics, BatteryState and the arrays serialized by the bridge itself: CDR, published raw.

Every second the bridge publishes ~340 key/value pairs. Through rclpy that costs two
passes over Python objects: building a KeyValue per pair, then rclpy converting each back
into C strings to serialize them (~1 us a pair, measured: the DDS write of the 13 kB result
takes 3 us). About three quarters of the pairs are unchanged from one second to the next,
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
message objects was most of a publish (~12 us; the DDS write of the bytes ~3 us) and most
of the code a cold publish runs.
"""
from __future__ import annotations

from array import array
import functools
import math
import struct
from typing import Any, Iterable

from rclpy.serialization import deserialize_message, serialize_message

from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray

from ams_can_bridge import reports
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport, Level

_U32 = struct.Struct('<I').pack
_STAMP_PACK = struct.Struct('<II').pack
_PADS = (b'', b'\0', b'\0\0', b'\0\0\0')


def _stamp(sec: int, nanosec: int) -> bytes:
    # int32 sec wraps past 2038 as rclpy's C conversion does
    return _STAMP_PACK(sec & 0xFFFFFFFF, nanosec)


def cdr_string(text: str) -> bytes:
    """Return a CDR string: uint32 length (with the NUL), UTF-8 bytes, NUL (4-aligned start)."""
    data = text.encode('utf-8')
    return _U32(len(data) + 1) + data + b'\0'


def _pair(key: str, value: str) -> bytes:
    """Return a key/value pair's bytes: it starts 4-aligned, so they never depend on where."""
    key_part = cdr_string(key)
    return key_part + _PADS[-len(key_part) & 3] + cdr_string(value)


class DiagnosticsEncoder:
    """Serialize DiagnosticArray messages to CDR, reusing the bytes of unchanged pairs."""

    def __init__(self) -> None:
        """Start with no pairs known; the encapsulation header is rclpy's own."""
        self._header = serialize_message(DiagnosticArray())[:4]
        # (status name, key) -> (value, bytes): bounded by the keys the devices report
        self._pairs: dict[tuple[str, str], tuple[str, bytes]] = {}

    def encode(self, stamp: float, statuses: Iterable[tuple[str, DiagnosticReport]],
               hardware_id: str, frame_id: str = '') -> bytes:
        """Return the serialized DiagnosticArray of (status name, report) at stamp."""
        sec, nanosec = reports.stamp_parts(stamp)
        statuses = list(statuses)
        body = [_stamp(sec, nanosec), cdr_string(frame_id)]
        pos = 8 + len(body[1])
        body.append(_PADS[-pos & 3] + _U32(len(statuses)))
        pos += (-pos & 3) + 4
        hardware = cdr_string(hardware_id)
        pairs = self._pairs
        for name, report in statuses:
            # level (1 byte), then three strings and the pair count, each 4-aligned
            level = bytes((int(report.level),))
            name_part, message = cdr_string(name), cdr_string(report.message)
            pad = -(pos + 1) & 3
            head = (level + _PADS[pad] + name_part + _PADS[-len(name_part) & 3] + message
                    + _PADS[-len(message) & 3] + hardware + _PADS[-len(hardware) & 3]
                    + _U32(len(report.values)))
            body.append(head)
            pos += len(head)
            for key, value in report.values.items():
                key, value = str(key), str(value)
                known = pairs.get((name, key))
                if known is None or known[0] != value:
                    known = (value, _pair(key, value))
                    pairs[(name, key)] = known
                padding = _PADS[-pos & 3]
                body.append(padding)
                body.append(known[1])
                pos += len(padding) + len(known[1])
        return self._header + b''.join(body)

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


_BATTERY_HEADER = serialize_message(BatteryState())[:4]


def battery_state(report: BatteryReport, frame_id: str,
                  fallback_stamp: float | None = None) -> bytes:
    """Serialize the BatteryState convert builds from the same report, as rclpy would."""
    f = reports.battery_fields(report)
    sec, nanosec = reports.stamp_parts(reports.report_stamp(report, fallback_stamp))
    frame = cdr_string(frame_id)
    cells = reports.float32_array(f['cell_voltage'])
    temps = reports.float32_array(f['cell_temperature'])
    location = cdr_string(f['location'])
    return b''.join((
        _BATTERY_HEADER, _stamp(sec, nanosec), frame, _PADS[-len(frame) & 3],
        # array('f') converts as rclpy does (a C cast: out of float32 range is inf)
        array('f', (f['voltage'], f['temperature'], f['current'], f['charge'], f['capacity'],
                    f['design_capacity'], f['percentage'])).tobytes(),
        bytes((f['power_supply_status'], f['power_supply_health'],
               f['power_supply_technology'], f['present'])),
        _U32(len(cells)), cells.tobytes(), _U32(len(temps)), temps.tobytes(),
        location, _PADS[-len(location) & 3], cdr_string(f['serial_number'])))


@functools.lru_cache(maxsize=64)
def _array_layout(rows: int, cols: int, labels: tuple[str, str]) -> bytes:
    out = serialize_message(Float32MultiArray())[:4] + _U32(2)
    for label, size, stride in reports.array_dims(rows, cols, labels):
        text = cdr_string(label)
        out += text + _PADS[-len(text) & 3] + _U32(size) + _U32(stride)
    return out + _U32(0)  # data_offset


def multi_array(rows: int, cols: int, data: Iterable[float],
                labels: tuple[str, str] = ('bank', 'sensor')) -> bytes:
    """Serialize the Float32MultiArray convert builds from the same data, as rclpy would."""
    values = reports.float32_array(data)
    return _array_layout(rows, cols, labels) + _U32(len(values)) + values.tobytes()


def _same(raw: bytes, msg: Any) -> bool:
    """Tell whether a subscriber reads the bytes as it reads the message (NaN == NaN)."""
    kind = type(msg)
    return (repr(deserialize_message(raw, kind))
            == repr(deserialize_message(serialize_message(msg), kind)))


def check_telemetry() -> bool:
    """Tell whether rclpy reads battery_state() and multi_array() as convert's messages."""
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
        for rows, cols, labels in ((2, 3, ('bank', 'sensor')), (1, 5, ('module', 'cell'))):
            data = [float(k) for k in range(rows * cols - 1)] + [nan]
            if not _same(multi_array(rows, cols, data, labels),
                         convert.multi_array(rows, cols, data, labels)):
                return False
    except Exception:
        return False
    return True
