# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""A CAN log written from simulated devices in simulated time (for tests and benchmarks)."""
from __future__ import annotations

from typing import Sequence

import can

from ams_can_bridge.sim.base import SimDevice

TICK = 0.002  # s, as SimRunner ticks


def write_log(path: str, simulators: Sequence[SimDevice], seconds: float,
              start: float = 1_790_000_000.0) -> int:
    """
    Tick the simulators from ``start`` (s since the epoch) for ``seconds``; log every frame.

    Each frame's timestamp is the simulated moment it was sent, the format is the one
    can.Logger picks from the suffix. Returns the number of frames written.
    """
    count = 0
    steps = int(round(seconds / TICK))
    with can.Logger(path) as log:
        for step in range(steps):
            now = start + step * TICK
            for sim in simulators:
                for frame in sim.tick(now):
                    log.on_message_received(can.Message(
                        timestamp=now, arbitration_id=frame.arbitration_id,
                        is_extended_id=frame.is_extended_id, data=frame.data,
                        is_fd=len(frame.data) > 8))
                    count += 1
    return count
