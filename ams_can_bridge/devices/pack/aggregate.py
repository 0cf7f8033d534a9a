# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
One BatteryReport from the members' (the table of doc/packs.md).

A sum or mean with an unknown part is unknown (NaN): a pack that hides a silent member's
share behind the others' numbers would report a battery that does not exist.
"""
from __future__ import annotations

import math
from typing import Sequence

from ams_can_bridge.devices.base import (BatteryReport, PowerSupplyHealth,
                                         PowerSupplyTechnology, current_status)

NAN = math.nan
PARALLEL = 'parallel'
SERIES = 'series'
CONNECTIONS = (PARALLEL, SERIES)

# Worst first: the pack's health is its worst member's (doc/packs.md).
HEALTH_ORDER = (PowerSupplyHealth.DEAD, PowerSupplyHealth.OVERHEAT,
                PowerSupplyHealth.OVERVOLTAGE, PowerSupplyHealth.COLD,
                PowerSupplyHealth.UNSPEC_FAILURE, PowerSupplyHealth.GOOD,
                PowerSupplyHealth.UNKNOWN)

_RANK = {int(h): i for i, h in enumerate(HEALTH_ORDER)}
_FALLBACK = _RANK[int(PowerSupplyHealth.UNSPEC_FAILURE)]

Members = Sequence[tuple[str, BatteryReport]]


def all_known(values: Sequence[float]) -> bool:
    """Tell whether there are values and none is NaN (or infinite): one C loop, no Python one."""
    # a sum propagates NaN and infinities: a report of 200 cells is checked per update
    return bool(values) and math.isfinite(sum(values))


def known_sum(values: Sequence[float]) -> float:
    """Return the sum, NaN when any part (or all: no parts) is unknown."""
    if not all_known(values):
        return NAN
    return math.fsum(values)


def known_mean(values: Sequence[float]) -> float:
    """Return the mean, NaN when any part is unknown."""
    total = known_sum(values)
    return total / len(values) if values else NAN


def known_min(values: Sequence[float]) -> float:
    """Return the minimum, NaN when any part is unknown (the unknown one may be lower)."""
    if not all_known(values):
        return NAN
    return min(values)


def known_max(values: Sequence[float]) -> float:
    """Return the maximum, NaN when any part is unknown (the unknown one may be higher)."""
    if not all_known(values):
        return NAN
    return max(values)


def worst_health(healths: Sequence[int]) -> int:
    """Return the worst member health by HEALTH_ORDER (a value outside it counts as failure)."""
    if not healths:
        return int(PowerSupplyHealth.UNKNOWN)
    return min((int(h) for h in healths), key=lambda h: _RANK.get(h, _FALLBACK))


def parallel_percentage(reports: Sequence[BatteryReport], charge: float,
                        capacity: float) -> float:
    """Charge / capacity when both known, else the capacity-weighted mean of the members'."""
    if math.isfinite(charge) and math.isfinite(capacity) and capacity > 0:
        return min(max(charge / capacity, 0.0), 1.0)
    percentages = [r.percentage for r in reports]
    if not all_known(percentages):
        return NAN
    weights = [r.capacity for r in reports]
    if not all(math.isfinite(w) and w > 0 for w in weights):
        weights = [1.0] * len(reports)  # equal weights without capacities
    return math.fsum(p * w for p, w in zip(percentages, weights)) / math.fsum(weights)


def aggregate(members: Members, connection: str) -> BatteryReport:
    """Return the pack's report from its members' (in member order)."""
    reports = [report for _, report in members]
    if connection == SERIES:
        voltage = known_sum([r.voltage for r in reports])
        current = known_mean([r.current for r in reports])
        charge = known_min([r.charge for r in reports])
        capacity = known_min([r.capacity for r in reports])
        design = known_min([r.design_capacity for r in reports])
        percentage = known_min([r.percentage for r in reports])
    else:
        voltage = known_mean([r.voltage for r in reports])
        current = known_sum([r.current for r in reports])
        charge = known_sum([r.charge for r in reports])
        capacity = known_sum([r.capacity for r in reports])
        design = known_sum([r.design_capacity for r in reports])
        percentage = parallel_percentage(reports, charge, capacity)
    technologies = {r.power_supply_technology for r in reports}
    technology = (technologies.pop() if len(technologies) == 1
                  else int(PowerSupplyTechnology.UNKNOWN))
    stamps = [r.stamp for r in reports if r.present and math.isfinite(r.stamp)]
    cells: list[float] = []
    temps: list[float] = []
    for r in reports:  # extend: a C loop over each member's array
        cells.extend(r.cell_voltage)
        temps.extend(r.cell_temperature)
    return BatteryReport(
        stamp=max(stamps) if stamps else NAN, voltage=voltage,
        temperature=known_max([r.temperature for r in reports]), current=current,
        charge=charge, capacity=capacity, design_capacity=design, percentage=percentage,
        power_supply_status=int(current_status(current)),
        power_supply_health=worst_health([r.power_supply_health for r in reports]),
        power_supply_technology=technology, present=any(r.present for r in reports),
        cell_voltage=cells, cell_temperature=temps)


def voltage_mismatch_pairs(members: Members,
                           max_difference: float) -> list[tuple[str, float, str, float]]:
    """Return each pair of parallel members whose voltages differ by more than allowed."""
    found = []
    for i, (name_a, a) in enumerate(members):
        for name_b, b in members[i + 1:]:
            if math.isfinite(a.voltage) and math.isfinite(b.voltage) \
                    and abs(a.voltage - b.voltage) > max_difference:
                found.append((name_a, a.voltage, name_b, b.voltage))
    return found


def voltage_mismatch_text(pair: tuple[str, float, str, float], max_difference: float) -> str:
    """Name both members of a mismatched pair and their voltages."""
    name_a, volts_a, name_b, volts_b = pair
    return (f'{name_a} {volts_a:.3f} V and {name_b} {volts_b:.3f} V '
            f'differ by more than {max_difference:g} V')


def voltage_mismatches(members: Members, max_difference: float) -> list[str]:
    """Name each pair of parallel members whose voltages differ by more than allowed."""
    return [voltage_mismatch_text(pair, max_difference)
            for pair in voltage_mismatch_pairs(members, max_difference)]


def cell_sum_mismatches(members: Members, max_difference: float) -> list[str]:
    """Name each member whose known cells do not add up to its own measured voltage."""
    found = []
    for name, report in members:
        total = sum(report.cell_voltage)
        if not report.cell_voltage or not math.isfinite(total) \
                or not math.isfinite(report.voltage):
            continue
        if abs(total - report.voltage) > max_difference:
            found.append(f'{name}: cells sum to {total:.3f} V, measured {report.voltage:.3f} V '
                         f'(more than {max_difference:g} V apart)')
    return found
