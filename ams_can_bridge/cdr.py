# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
CDR (XCDR1, little-endian) of /diagnostics, BatteryState and Float32MultiArray, without ROS.

The bytes rclpy's ``serialize_message`` gives for the messages ``ros/convert.py`` builds
from the same reports, built with ``struct`` and ``array`` in a few joins: the live bridge
publishes them raw (``ros/diag_cdr.py`` checks them against rclpy once at start), log2bag
writes them into its bags (cheaper than rosbags' message objects and serializer;
test_log2bag_golden.py holds the bags byte-identical to what they gave).

The layout: a 4-byte encapsulation header, then each field aligned to its size counted
from the end of that header; a string is a uint32 length (with the NUL), its UTF-8 bytes
and a NUL. Reusing the bytes of unchanged key/value pairs: ``DiagnosticsEncoder``.
"""
from __future__ import annotations

from array import array
import functools
import struct
from typing import Iterable

from ams_can_bridge import reports
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport

CDR_LE = b'\0\1\0\0'  # encapsulation: CDR, little-endian (rclpy's and rosbags')

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


def _pad4(data: bytes) -> bytes:
    """Return data with the zero bytes that make its length a multiple of 4."""
    return data + _PADS[-len(data) & 3]


_PADDED: dict[str, bytes] = {}  # frame ids, status names, hardware ids: kept


def _padded_string(text: str) -> bytes:
    """Return cdr_string(text) padded to 4 (a frame_id, a status name), kept for a few."""
    known = _PADDED.get(text)
    if known is None:
        known = _pad4(cdr_string(text))
        if len(_PADDED) < 256:  # a node's devices; a growing set is never kept
            _PADDED[text] = known
    return known


class DiagnosticsEncoder:
    """Serialize DiagnosticArray messages to CDR, reusing the bytes of unchanged pairs."""

    def __init__(self) -> None:
        """Start with no pairs known."""
        self._header = CDR_LE
        # status name -> key -> (value, the pair's bytes padded to 4, that padding's length):
        # bounded by the keys the devices report
        self._pairs: dict[str, dict[str, tuple[str, bytes, int]]] = {}
        self._keys: dict[str, bytes] = {}  # key -> its CDR string padded to 4: as bounded

    def encode(self, stamp: float, statuses: Iterable[tuple[str, DiagnosticReport]],
               hardware_id: str, frame_id: str = '') -> bytes:
        """Return the serialized DiagnosticArray of (status name, report) at stamp."""
        sec, nanosec = reports.stamp_parts(stamp)
        statuses = list(statuses)
        body = [_stamp(sec, nanosec), cdr_string(frame_id)]
        pos = 8 + len(body[1])
        body.append(_PADS[-pos & 3] + _U32(len(statuses)))
        pos += (-pos & 3) + 4
        hardware = _padded_string(hardware_id)
        every_pair = self._pairs
        keys = self._keys
        append = body.append
        for name, report in statuses:
            # level (1 byte), then three strings and the pair count, each 4-aligned
            values = report.values
            message = cdr_string(report.message)
            head = (bytes((int(report.level),)) + _PADS[-(pos + 1) & 3] + _padded_string(name)
                    + message + _PADS[-len(message) & 3] + hardware + _U32(len(values)))
            append(head)
            pos += len(head)  # 4-aligned: the pair count ends it
            if not values:
                continue
            pairs = every_pair.get(name)
            if pairs is None:
                pairs = every_pair[name] = {}
            # A pair starts 4-aligned: each is kept padded for the next pair; the last of a
            # status goes unpadded (the next status starts with its 1-byte level).
            last_pad = 0
            for key, value in values.items():
                if type(key) is not str:
                    key = str(key)
                if type(value) is not str:
                    value = str(value)
                known = pairs.get(key)
                if known is None or known[0] != value:
                    # a changed value: the key's bytes (padded, it starts 4-aligned) are kept
                    key_part = keys.get(key)
                    if key_part is None:
                        key_part = keys[key] = _pad4(cdr_string(key))
                    data = value.encode('utf-8')
                    pad = -(len(data) + 5) & 3  # after the length, the bytes and the NUL
                    known = pairs[key] = (value, b''.join(
                        (key_part, _U32(len(data) + 1), data, b'\0', _PADS[pad])), pad)
                append(known[1])
                pos += len(known[1])
                last_pad = known[2]
            if last_pad:
                body[-1] = body[-1][:-last_pad]
                pos -= last_pad
        return self._header + b''.join(body)


def restamp(message: bytes, sec: int, nanosec: int) -> bytes:
    """Return a serialized message that starts with a std_msgs/Header, stamped anew."""
    return message[:4] + _stamp(sec, nanosec) + message[12:]


def battery_state_at(report: BatteryReport, frame_id: str, sec: int, nanosec: int) -> bytes:
    """
    Serialize the BatteryState of a report with header stamp (sec, nanosec).

    The fields of ``reports.battery_fields`` read straight from the report (that dict was
    half of this call, on every primary frame): ``+ 0.0`` makes -0.0 0.0 as there.
    """
    r = report
    cells = _float32_sequence(r.cell_voltage)
    temps = _float32_sequence(r.cell_temperature)
    return b''.join((
        CDR_LE, _STAMP_PACK(sec & 0xFFFFFFFF, nanosec), _padded_string(frame_id),
        # array('f') converts as rclpy does (a C cast: out of float32 range is inf)
        array('f', (r.voltage + 0.0, r.temperature + 0.0, r.current + 0.0, r.charge + 0.0,
                    r.capacity + 0.0, r.design_capacity + 0.0, r.percentage + 0.0)).tobytes(),
        bytes((r.power_supply_status, r.power_supply_health, r.power_supply_technology,
               bool(r.present))),
        cells, temps, _padded_string(r.location), cdr_string(r.serial_number)))


def _float32_sequence(values: list[float]) -> bytes:
    """Return a float32[] as CDR: the count, then the values (-0.0 written 0.0)."""
    data = array('f', values).tobytes()
    if reports.F32_NEGATIVE_ZERO in data:  # float32_array's test, on bytes made once
        data = reports.float32_array(values).tobytes()
    return _U32(len(data) >> 2) + data


@functools.lru_cache(maxsize=64)
def _array_layout(rows: int, cols: int, labels: tuple[str, str]) -> bytes:
    out = CDR_LE + _U32(2)
    for label, size, stride in reports.array_dims(rows, cols, labels):
        text = cdr_string(label)
        out += text + _PADS[-len(text) & 3] + _U32(size) + _U32(stride)
    return out + _U32(0)  # data_offset


def float32(value: float) -> bytes:
    """Return a std_msgs/Float32's bytes (a C cast to float, as rclpy's: out of range is inf)."""
    return CDR_LE + array('f', (value,)).tobytes()


def multi_array(rows: int, cols: int, data: Iterable[float],
                labels: tuple[str, str] = ('bank', 'sensor')) -> bytes:
    """Serialize the Float32MultiArray of row-major rows x cols data."""
    values = reports.float32_array(data)
    return _array_layout(rows, cols, labels) + _U32(len(values)) + values.tobytes()


class ArrayEncoder:
    """
    Serialize Float32MultiArray messages, reusing a topic's bytes while its data is unchanged.

    An array has no header: equal data gives equal bytes. A car's temperature arrays change
    a few times a minute but go out with every primary frame (2,400 of a 120 s car mix's
    6,361 messages were the same as the topic's last; bench/README.md, third pass). Equal
    lists give equal float32 bytes (0.0 == -0.0, and both are written 0.0); NaN is unequal
    to itself, so an array holding one is serialized again, never wrongly reused.
    """

    def __init__(self) -> None:
        """Start with no topic known."""
        # topic -> (rows, cols, a copy of the data, bytes): one entry per array topic
        self._last: dict[str, tuple[int, int, list[float], bytes]] = {}

    def encode(self, topic: str, rows: int, cols: int, data: list[float]) -> bytes:
        """Return the serialized Float32MultiArray of row-major rows x cols data."""
        last = self._last.get(topic)
        if last is not None and last[2] == data and last[0] == rows and last[1] == cols:
            return last[3]
        raw = multi_array(rows, cols, data)
        self._last[topic] = (rows, cols, list(data), raw)  # a copy: a device may reuse its list
        return raw
