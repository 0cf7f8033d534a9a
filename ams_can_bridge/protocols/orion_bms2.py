# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Orion BMS 2's checksum byte: the one rule of its standard messages a DBC cannot express.

Byte 7 of 0x6B0, 0x6B1 and the cell broadcast 0x36 is ``(ID + 8 + bytes 0..6) & 0xFF`` (the
Orion utility's DBC exports name it ``CRC_Checksum``; 8 is the frame's length). It holds in
every 0x6B0/0x6B1 frame of a real car's capture (doc/protocols.md section 8, [ORION-CAR]:
302 of 302). The bridge does not check it (a frame is read by its DBC); probe takes it as
proof of the sender, and the simulator sends it as the device does.
"""
from __future__ import annotations

CHECKSUM_IDS = (0x6B0, 0x6B1, 0x36)  # the standard messages and the cell broadcast
CHECKSUM_LENGTH = 8


def checksum(can_id: int, data: bytes | bytearray) -> int:
    """Return the checksum byte of an 8-byte frame: (ID + 8 + bytes 0..6) & 0xFF."""
    return (can_id + CHECKSUM_LENGTH + sum(data[:7])) & 0xFF


def checksum_right(can_id: int, data: bytes | bytearray) -> bool:
    """Tell whether an 8-byte frame carries its checksum byte right."""
    return len(data) == CHECKSUM_LENGTH and data[7] == checksum(can_id, data)


def with_checksum(can_id: int, data: bytes | bytearray) -> bytes:
    """Return an 8-byte frame's data with its checksum byte set, as the device sends it."""
    return bytes(data[:7]) + bytes((checksum(can_id, data),))
