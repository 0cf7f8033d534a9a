"""
/diagnostics serialized by the bridge itself: CDR bytes, published raw.

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
"""
from __future__ import annotations

import struct
from typing import Any, Iterable

from rclpy.serialization import deserialize_message, serialize_message

from diagnostic_msgs.msg import DiagnosticArray

from ams_can_bridge import reports
from ams_can_bridge.devices.base import DiagnosticReport, Level

_U32 = struct.Struct('<I').pack
_STAMP = struct.Struct('<iI').pack
_PADS = (b'', b'\0', b'\0\0', b'\0\0\0')


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
        body = [_STAMP(sec, nanosec), cdr_string(frame_id)]
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
                pad = _PADS[-pos & 3]
                body.append(pad)
                body.append(known[1])
                pos += len(pad) + len(known[1])
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
