# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The example BMS's wire format: one status frame, one command frame (no ROS, no state).

Status, ID ``base_id``, DLC 8, every 200 ms, little-endian:

====== ======================================================================
bytes  value
====== ======================================================================
0..1   pack voltage, unsigned, 0.01 V
2..3   pack current, signed, 0.1 A, positive while charging (as ROS counts it)
4      state of charge, % (0..100)
5      temperature, degC + 40 (0 = -40 degC)
6      flags: bit 0 = fault (the other bits are reserved, 0)
7      layout version, 1
====== ======================================================================

Reset SoC, ID ``base_id + 1``, DLC 1, data ``A5``: the BMS sets its SoC to 100 %.
"""
from __future__ import annotations

from dataclasses import dataclass
import struct

from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.common import Frame

DEFAULT_BASE_ID = 0x6B0
STATUS_PERIOD_S = 0.2
LAYOUT_VERSION = 1
RESET_SOC = 1  # offset of the command frame from base_id
RESET_SOC_DATA = b'\xa5'
FAULT = 0x01
_STATUS = struct.Struct('<HhBBBB')


@dataclass(frozen=True)
class Status:
    """One status frame, in physical units."""

    voltage_v: float
    current_a: float  # positive while charging
    soc_pct: int
    temperature_c: int
    fault: bool


class ExampleCodec:
    """Decode the status frame at base_id; build the status (simulator) and the command."""

    is_extended_id = False

    def __init__(self, base_id: int = DEFAULT_BASE_ID) -> None:
        """Take the status ID; the command goes to the next one."""
        self.base_id = base_id
        self.arbitration_ids = frozenset({base_id})

    def decode(self, arbitration_id: int, data: bytes) -> Status:
        """Return the status of one frame; MalformedFrameError for anything else."""
        if arbitration_id != self.base_id:
            raise MalformedFrameError(arbitration_id, data, 'not the example BMS status ID')
        if len(data) != _STATUS.size:
            raise MalformedFrameError(arbitration_id, data, f'DLC {len(data)}, not 8')
        volts, amps, soc, temp, flags, version = _STATUS.unpack(data)
        if version != LAYOUT_VERSION or flags & ~FAULT or soc > 100:
            raise MalformedFrameError(arbitration_id, data, 'not the example status layout')
        return Status(volts / 100, amps / 10, soc, temp - 40, bool(flags & FAULT))

    def encode_status(self, status: Status) -> Frame:
        """Build the status frame (the simulator sends it)."""
        data = _STATUS.pack(round(status.voltage_v * 100), round(status.current_a * 10),
                            status.soc_pct, status.temperature_c + 40,
                            FAULT if status.fault else 0, LAYOUT_VERSION)
        return Frame(self.base_id, data)

    def reset_soc(self) -> Frame:
        """Build the reset-SoC command."""
        return Frame(self.base_id + RESET_SOC, RESET_SOC_DATA)
