# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What 0x35F bytes 4-5 carry: the pack's capacity (SMA's TI) or the charge left in it.

SMA's TI has 0x35F's Ah as the battery's capacity, and most senders send that. Victron-
dialect batteries that also send their installed capacity in 0x379 may send what is left
instead: a BYD Battery-Box Premium LVS of 2 x 78 Ah sends `35F ... 69 00` = 105 Ah at SoC
67 % with `379 9C 00` = 156 Ah, and its own code names the field "available capacity in
Ampere hours" (doc/protocols.md section 5.2). The battery's own evidence tells the two
apart: 0x35F against SoC x 0x379. ``decide_info_capacity`` is pure (no clock, no ROS), so a
device and a tool reading a log decide alike; the device keeps what the evidence settles.
"""
from __future__ import annotations

from dataclasses import dataclass

CAPACITY = 'capacity'  # 0x35F is the capacity (SMA's TI): today's reading
CHARGE = 'charge'  # 0x35F is the charge left (Ah), 0x379 the capacity
# Fraction of the installed capacity within which 0x35F "agrees" with a value: both are whole
# Ah and the SoC whole %, so a pack of 100 Ah at 51 % may send 50 or 52 (a few % apart).
AGREEMENT = 0.03
ROUNDING_AH = 1.0  # never tighter than the whole Ah both frames are sent in


@dataclass(frozen=True)
class InfoCapacityDecision:
    """What the evidence settles 0x35F's Ah to be (None: it does not) and why, in words."""

    meaning: str | None
    reason: str


def decide_info_capacity(info_ah: float, installed_ah: float | None,
                         soc_pct: float | None) -> InfoCapacityDecision:
    """
    Decide whether 0x35F's Ah (info_ah) is the capacity or the charge left.

    installed_ah: the battery's 0x379; soc_pct: its 0x355 SoC. 0x35F is the charge when it
    agrees with SoC x 0x379 (within AGREEMENT of 0x379) and not with 0x379 itself, the
    capacity when it agrees with 0x379 and not with SoC x 0x379; otherwise nothing is
    settled (no 0x379 or SoC, a full pack where both agree, or neither agrees).
    """
    if installed_ah is None or soc_pct is None:
        return InfoCapacityDecision(None, 'no 0x379 installed capacity and 0x355 SoC to '
                                          'compare with')
    left = installed_ah * soc_pct / 100
    tolerance = max(ROUNDING_AH, AGREEMENT * installed_ah)
    is_charge = abs(info_ah - left) <= tolerance
    is_capacity = abs(info_ah - installed_ah) <= tolerance
    facts = (f'0x35F {info_ah:g} Ah, SoC {soc_pct:g} % of the installed {installed_ah:g} Ah '
             f'is {left:g} Ah')
    if is_charge and not is_capacity:
        return InfoCapacityDecision(CHARGE, f'{facts}: the charge left, not the capacity')
    if is_capacity and not is_charge:
        return InfoCapacityDecision(CAPACITY, f'{facts}: 0x35F is the installed capacity')
    if is_charge:
        return InfoCapacityDecision(None, f'{facts}: both fit (a full pack)')
    return InfoCapacityDecision(None, f'{facts}: 0x35F fits neither')
