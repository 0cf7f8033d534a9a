# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Simulated devices: the contract the runner (bus I/O) and the device models share.

A simulator is a pure model: time in, frames out, frames in. It never touches a bus, a
thread or a clock of its own, so tests step it deterministically and the same objects run
under ``SimRunner`` in ``simulator``, ``demo`` and the benchmarks.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ams_can_bridge.protocols.common import Frame


@dataclass
class Faults:
    """Fault injection switches shared by every simulator (each model honours them)."""

    silent: bool = False          # send nothing (device unplugged / dead)
    malformed: bool = False       # send its periodic frames with a wrong DLC
    error_code: int | None = None  # report this vendor error code
    cell_drift_v: float = 0.0     # added to one cell (index drift_cell) over time
    drift_cell: int = 0
    extra: dict[str, Any] = field(default_factory=dict)


class SimDevice:
    """
    Base of every simulated device.

    ``tick(now)`` returns the frames due at ``now`` (seconds, any monotonic origin) and
    advances the physics; ``on_frame(frame, now)`` takes a frame from the bus. Models
    schedule their periodic frames from ``now`` (not from call counts) so a late tick sends
    what is due without drifting.
    """

    TYPE = ''

    def __init__(self, name: str | None = None) -> None:
        self.name = name or self.TYPE
        self.faults = Faults()

    def tick(self, now: float) -> list[Frame]:
        """Return the frames due at ``now`` (empty while faults.silent)."""
        raise NotImplementedError

    def on_frame(self, frame: Frame, now: float) -> None:
        """Take a frame seen on the bus (commands addressed to this device, or anything)."""

    @staticmethod
    def corrupt(frame: Frame) -> Frame:
        """Return the frame with one byte dropped (or one added if empty): a wrong DLC."""
        data = frame.data[:-1] if frame.data else b'\x00'
        return Frame(frame.arbitration_id, data, frame.is_extended_id)


class Periodic:
    """A period scheduled on absolute times: due() is True once per period, never drifting."""

    def __init__(self, period: float, phase: float = 0.0) -> None:
        self.period = period
        self.next: float | None = None
        self.phase = phase

    def due(self, now: float) -> bool:
        """Tell (and advance) when the next slot has come; missed slots are skipped."""
        if self.next is None:
            self.next = now + self.phase
        if now + 1e-9 < self.next:
            return False
        # max(0, ...): within the 1e-9 tolerance now - next is a tiny negative, whose floor
        # division is -1; without the clamp next would never advance and fire every tick.
        missed = max(0, int((now - self.next) // self.period))
        self.next += (missed + 1) * self.period
        return True
