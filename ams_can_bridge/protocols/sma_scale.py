# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Which scale a battery's 0x356 voltage is in: SMA's 0.01 V, or the 0.1 V some senders use.

A Discover Lynx II and an Orion BMS 2 put 0x356's voltage in 0.1 V (doc/protocols.md
section 5.2): 52.2 V arrives as 522. The battery's own evidence tells the two apart:
0x351's voltage limits (always 0.1 V), its cell voltages (0x373, or 0x370 as Pylontech V2
and Seplos send it) and, where known, its cell count. ``decide_voltage_scale`` is pure (no
clock, no ROS) so that a device and a tool reading a log decide the same way.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ams_can_bridge.protocols.sma import SmaBattery, SmaLimits

SMA_VOLTAGE_SCALE = 0.01  # V per bit of 0x356 bytes 0-1, SMA's TI
TENTH_VOLT_SCALE = 0.1  # V per bit as the Discover Lynx II and the Orion BMS 2 send it
VOLTAGE_SCALES = (SMA_VOLTAGE_SCALE, TENTH_VOLT_SCALE)
# A pack may sag below its discharge voltage limit under load and overshoot its charge
# voltage limit a little: the window is [DVL x 0.75, CVL x 1.25]. The two scales are 10x
# apart, so the windows of one 0x356 at both scales never both fit unless CVL/DVL >= 6.
LIMIT_MARGIN = 0.25
# Without a discharge voltage limit the window starts at half the charge voltage limit: no
# chemistry's empty pack is below half its charge voltage (LFP 2.5 / 3.65 V, NMC 3.0 / 4.2 V,
# lead-acid 10.5 / 14.4 V).
NO_DVL_FRACTION = 0.5
# The pack voltage is the sum of its cells, measured by another ADC at another moment.
CELL_MARGIN = 0.03
MAX_CELLS = 400
# V a cell of any battery chemistry an SMA-protocol BMS manages (LTO 1.5 .. NMC 4.35 V).
CELL_RANGE_V = (1.0, 5.0)


@dataclass(frozen=True)
class ScaleDecision:
    """The scale the evidence settles (None: it does not) and why, in words for a user."""

    scale: float | None
    reason: str


def raw_voltage(battery: SmaBattery) -> int | None:
    """Return 0x356's voltage as sent (the raw count), None for the 0x8000 marker."""
    return None if battery.voltage_v is None else round(battery.voltage_v / SMA_VOLTAGE_SCALE)


def _volts(raw: int, scale: float) -> float:
    return raw / round(1 / scale)  # 522 / 10 = 52.2 exactly, as the sender meant it


def _at(raw: int, scale: float) -> str:
    return f'{_volts(raw, scale):g} V at {scale:g} V/bit'


def _by_limits(raw: int, limits: SmaLimits | None) -> tuple[list[float], str] | None:
    if limits is None or not limits.charge_voltage_v:
        return None  # no limits, or 0 (a BMS in standby): no evidence
    high = limits.charge_voltage_v
    low = limits.discharge_voltage_v
    if low is not None and low > high:
        return None
    bottom = low * (1 - LIMIT_MARGIN) if low else high * NO_DVL_FRACTION
    fits = [s for s in VOLTAGE_SCALES if bottom <= _volts(raw, s) <= high * (1 + LIMIT_MARGIN)]
    limit_text = f'{low:g}..{high:g} V' if low else f'up to {high:g} V'
    return fits, f'the 0x351 limits {limit_text}'


def _by_cells(raw: int, cells_v: tuple[float, float] | None,
              cell_count: int | None) -> tuple[list[float], str] | None:
    if cells_v is not None and cells_v[0] > 0 and cells_v[1] >= cells_v[0]:
        low, high = cells_v
        text = f'cells of {low:g}..{high:g} V'
    elif cell_count:
        low, high = CELL_RANGE_V
        text = f'{cell_count} cells of {low:g}..{high:g} V each'
    else:
        return None
    fits = []
    for s in VOLTAGE_SCALES:
        volts = _volts(raw, s)
        first = max(1, math.ceil(volts / (high * (1 + CELL_MARGIN))))
        last = min(MAX_CELLS, math.floor(volts / (low * (1 - CELL_MARGIN))))
        if first <= last and (cell_count is None or first <= cell_count <= last):
            fits.append(s)
    return fits, text


def decide_voltage_scale(voltage_raw: int, limits: SmaLimits | None = None,
                         cells_v: tuple[float, float] | None = None,
                         cell_count: int | None = None) -> ScaleDecision:
    """
    Decide 0x356's voltage scale from the battery's own evidence, strongest first.

    voltage_raw: 0x356 bytes 0-1 as sent (``raw_voltage``); limits: the battery's 0x351;
    cells_v: its lowest and highest cell voltage (0x373 or a binary 0x370); cell_count:
    its cell count where known. A voltage that fits one piece of evidence at one scale and
    not at the other settles it; ScaleDecision.scale is None when nothing does.
    """
    checks = [_by_limits(voltage_raw, limits), _by_cells(voltage_raw, cells_v, cell_count)]
    tried = []
    for check in checks:
        if check is None:
            continue
        fits, what = check
        if len(fits) == 1:
            other = next(s for s in VOLTAGE_SCALES if s != fits[0])
            return ScaleDecision(fits[0], f'{_at(voltage_raw, fits[0])} fits {what}, '
                                          f'{_at(voltage_raw, other)} does not')
        tried.append(f'{what} fit {"both" if fits else "neither"}')
    if not tried:
        return ScaleDecision(None, 'no evidence yet (no 0x351 voltage limits, no cell '
                                   'voltages)')
    return ScaleDecision(None, f'{_at(voltage_raw, SMA_VOLTAGE_SCALE)} or '
                               f'{_at(voltage_raw, TENTH_VOLT_SCALE)}: ' + '; '.join(tried))


def scaled_voltage(voltage_raw: int | None, scale: float | None) -> float | None:
    """Return 0x356's voltage in V at a decided scale (None: marker or scale undecided)."""
    if voltage_raw is None or scale is None:
        return None
    return _volts(voltage_raw, scale)
