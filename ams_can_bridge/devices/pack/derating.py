# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Charge/discharge current limits derated from MOL (100 %) to RSL (0), like dbus-serialbattery.

The charge limit follows ``cell_voltage_max`` and both temperature limits, the discharge limit
``cell_voltage_min`` and both temperature limits; the lowest factor wins.
"""
from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

from ams_can_bridge.devices.pack.limits import KINDS

CHARGE_INPUTS = ('cell_voltage_max', 'temperature_max', 'temperature_min')
DISCHARGE_INPUTS = ('cell_voltage_min', 'temperature_max', 'temperature_min')


def factor(name: str, value: float, levels: Sequence[float]) -> float:
    """Return 1 inside MOL, 0 at or beyond RSL, linear between; 0 when the value is unknown."""
    if math.isnan(value):
        return 0.0  # fail-safe: a limit nobody can check allows nothing
    mol, rsl = levels[0], levels[1]
    # distance still left before RSL, as a share of the MOL..RSL band
    share = (rsl - value) / (rsl - mol) if KINDS[name].upper else (value - rsl) / (mol - rsl)
    return min(max(share, 0.0), 1.0)


def derated(maximum: float, inputs: Sequence[str], levels: Mapping[str, Sequence[float]],
            value: Callable[[str], float]) -> float:
    """
    Return ``maximum`` times the lowest factor of the configured inputs (NaN: no maximum).

    ``value(name)``: the watched value of a limit (``Limits.value``: computed once per report).
    """
    if not maximum > 0:
        return math.nan  # not configured: the pack does not know a limit
    lowest = 1.0
    for name in inputs:
        if name in levels:
            lowest = min(lowest, factor(name, value(name), levels[name]))
    return maximum * lowest
