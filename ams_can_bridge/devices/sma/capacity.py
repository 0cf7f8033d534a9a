# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
How an SMA device reads 0x35F's Ah: the capacity, or the charge left.

The evidence (``protocols.sma_capacity.decide_info_capacity``: 0x35F against SoC x 0x379)
decides; a decision it settles is kept (a full pack later fits both); until then 0x35F is
read as SMA's TI has it, the capacity. The diagnostics value ``capacity reading (0x35F)``
says which reading was taken and why.
"""
from __future__ import annotations

from typing import Any, Hashable, Mapping

from ams_can_bridge.protocols.sma import SmaBatteryInfo, SmaSoc
from ams_can_bridge.protocols.sma_capacity import (
    CAPACITY, CHARGE, decide_info_capacity, InfoCapacityDecision)
from ams_can_bridge.protocols.sma_dialects import VictronInstalledCapacity

LABEL = 'capacity reading (0x35F)'


class InfoCapacity:
    """0x35F's meaning for one device: from the evidence, kept once settled."""

    def __init__(self) -> None:
        self.settled: InfoCapacityDecision | None = None

    def reset(self) -> None:
        """Weigh the evidence anew (a configure)."""
        self.settled = None

    def read(self, readings: Mapping[Hashable, Any]) -> tuple[float | None, float | None, str]:
        """
        Return (capacity Ah, charge Ah or None = capacity x SoC, why) from fresh readings.

        The charge is given only where 0x35F is the charge; otherwise the caller multiplies.
        """
        info = readings.get(SmaBatteryInfo)
        installed = readings.get(VictronInstalledCapacity)
        installed_ah = None if installed is None else installed.capacity_ah
        info_ah = None if info is None else info.capacity_ah
        if info_ah is None:  # 0 or not sent: Victron's installed capacity (section 5.2)
            return (None if installed_ah is None else float(installed_ah)), None, ''
        soc: SmaSoc | None = readings.get(SmaSoc)
        soc_pct = None if soc is None else soc.percent
        decision = self.settled
        if decision is None:
            decision = decide_info_capacity(info_ah, installed_ah, soc_pct)
            if decision.meaning is not None:
                self.settled = decision
        if decision.meaning == CHARGE:
            return ((None if installed_ah is None else float(installed_ah)), float(info_ah),
                    f'charge left (auto: {decision.reason})')
        why = 'auto' if decision.meaning == CAPACITY else "undecided, SMA's TI reading"
        return float(info_ah), None, f'capacity ({why}: {decision.reason})'

    @property
    def is_charge(self) -> bool:
        """Tell whether the evidence settled 0x35F as the charge left."""
        return self.settled is not None and self.settled.meaning == CHARGE


def capacity_values(info_capacity: InfoCapacity,
                    readings: Mapping[Hashable, Any]) -> dict[str, str]:
    """Return the diagnostics values of 0x35F's Ah as read: which reading, and its label."""
    _, _, why = info_capacity.read(readings)
    values = {LABEL: why} if why else {}
    info = readings.get(SmaBatteryInfo)
    if info_capacity.is_charge and info is not None:
        values['capacity Ah'] = 'not sent (0x35F carries the charge left: 0x379)'
        values['charge left Ah (0x35F)'] = f'{info.capacity_ah:g}'
    return values
