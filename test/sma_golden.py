# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
SMA-protocol frames of a real battery, typed by hand, and an SMA device to feed them to.

Golden frames are never produced by our simulator or codec: each block names its source.
"""
from __future__ import annotations

from ams_can_bridge.devices.sma.device import SmaDevice
from helpers import Clock

# dfch/BydCanProtocol README.md: BYD Battery-Box Premium LVS talking to a Victron GX.
BYD_351 = bytes([0x48, 0x02, 0x00, 0x05, 0x00, 0x05, 0xAE, 0x01])  # 58.4 V, 128 A, 128 A, 43 V
BYD_355 = bytes([0x43, 0x00, 0x64, 0x00, 0x00, 0x00, 0x00, 0x00])  # 67 %, 100 %, zeros
BYD_356 = bytes([0xBE, 0x14, 0xF9, 0xFF, 0x8C, 0x00, 0x00, 0x00])  # 53.10 V, -0.7 A, 14.0 C
BYD_35A = bytes([0xAA] * 8)
BYD_35F = bytes([0x4C, 0x69, 0x01, 0x17, 0x69, 0x00, 0x00, 0x00])  # 105 Ah
BYD_372 = bytes([0x02, 0x00, 0x02, 0x00, 0x01, 0x00, 0x00, 0x00])
BYD_378 = bytes([0x40, 0x08, 0x00, 0x00, 0x2B, 0x07, 0x00, 0x00])  # 211.2 / 183.5 kWh
BYD_379 = bytes([0x9C, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00])  # 156 Ah
BYD_382 = bytes([0x50, 0x52, 0x45, 0x4D, 0x49, 0x55, 0x4D, 0x00])  # "PREMIUM"


def make() -> tuple[SmaDevice, Clock]:
    """Return an SMA device with no parameters set, on a test clock at 50 s."""
    clock = Clock(50.0)
    return SmaDevice('sma', {}, clock=clock), clock


def feed(device: SmaDevice, *frames: tuple[int, bytes]) -> None:
    """Hand the device (id, data) frames, each at t = 1 s."""
    for can_id, data in frames:
        device.handle_frame(can_id, data, 1.0)
