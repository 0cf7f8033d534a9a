# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Current profiles that make simulated packs move like real ones."""
from __future__ import annotations

import math


def drive_current_a(t: float) -> float:
    """
    Give a lap-like discharge current (A, positive = discharge): accelerate, brake, regen.

    Periodic over 20 s, between about -30 A (regeneration) and 120 A (full throttle),
    so SoC falls steadily while the signs of both directions show up in a short demo.
    """
    phase = t % 20.0
    base = 45.0 + 55.0 * math.sin(2 * math.pi * phase / 20.0)
    if 14.0 <= phase < 16.0:  # braking: recuperation
        return -30.0
    return base + 15.0 * math.sin(2 * math.pi * t / 1.3)


def charge_current_a(t: float, setpoint_a: float = 20.0) -> float:
    """Give a charging current (A, positive = discharge, so negative here) with ripple."""
    return -(setpoint_a + 0.3 * math.sin(2 * math.pi * t / 2.0))
