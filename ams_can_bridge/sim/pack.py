# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Pack physics shared by the simulators: time steps, charge counting, a thermal lag.

Each simulator keeps its own state and constants (capacity, heating, SoC scale); these
helpers only hold the arithmetic, written once, in the order the simulators always used
(their tests compare exact values).
"""
from __future__ import annotations

from typing import Sequence

THERMAL_TAU_S = 60.0  # s: time constant of the first-order temperature lag


class Elapsed:
    """
    Time since the previous step of a simulator.

    The first step has no previous one and counts as 0 s; time going backwards counts as 0 s
    too (a simulator is stepped with the runner's monotonic clock, tests may restart it).
    """

    def __init__(self) -> None:
        self.last: float | None = None

    def __call__(self, now: float) -> float:
        """Return the seconds since the previous call (see the class) and remember now."""
        dt = 0.0 if self.last is None else max(0.0, now - self.last)
        self.last = now
        return dt


def integrate_soc(soc: float, current_a: float, dt: float, capacity_ah: float,
                  full: float = 100.0) -> float:
    """
    Return the state of charge after current_a (A, positive = discharge) flowed for dt s.

    ``full`` is the scale of ``soc``: 100.0 for percent, 1.0 for a fraction; the result is
    held within 0..full.
    """
    return min(full, max(0.0, soc - current_a * dt / 3600.0 / capacity_ah * full))


def thermal_lag(temperature_c: float, target_c: float, dt: float,
                tau_s: float = THERMAL_TAU_S) -> float:
    """Move temperature_c towards target_c over dt s (first-order lag, time constant tau_s)."""
    return temperature_c + (target_c - temperature_c) * min(1.0, dt / tau_s)


def four(values: Sequence[float]) -> tuple[float, float, float, float]:
    """Return the four cell voltages of one BMS12 cell frame (a slice of a padded list)."""
    first, second, third, fourth = values
    return first, second, third, fourth
