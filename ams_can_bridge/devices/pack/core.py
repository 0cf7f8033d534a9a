# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The pack: its members' reports in, its BatteryState, limits, time-to-go and diagnostics out.

``Pack.update`` is called with every member's latest report each time one of them reports
(the engine does it); nothing here reads frames or sends any. Fail-safe: both current limits
are 0 while a member is stale or an MSL event is latched (doc/packs.md).
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import Mapping, Sequence

from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport, Level
from ams_can_bridge.devices.pack.aggregate import (PARALLEL, Members, aggregate,
                                                   cell_sum_mismatches, voltage_mismatch_pairs,
                                                   voltage_mismatch_text)
from ams_can_bridge.devices.pack.derating import CHARGE_INPUTS, DISCHARGE_INPUTS, derated
from ams_can_bridge.devices.pack.limits import Event, Limits, Severity
from ams_can_bridge.devices.pack.time_to_go import TimeToGo


@dataclass
class PackOutput:
    """What one pack update emits: the BatteryState and the four Float32 figures."""

    report: BatteryReport
    charge_current_limit: float
    discharge_current_limit: float
    time_to_empty: float
    time_to_full: float
    raised: list[Event] = field(default_factory=list)
    stale: list[str] = field(default_factory=list)
    # parallel members too far apart: formatted when read (the diagnostics, ~1 Hz), not at
    # every member report, where the float formatting was a tenth of the pack's cost
    mismatched: list[tuple[str, float, str, float]] = field(default_factory=list)
    max_voltage_difference: float = 1.5
    cell_sums: list[str] = field(default_factory=list)

    @property
    def warnings(self) -> list[str]:
        """Return the WARNs of this update: stale members, voltage mismatches, cell sums."""
        return ([f'{name} is stale' for name in self.stale]
                + [voltage_mismatch_text(pair, self.max_voltage_difference)
                   for pair in self.mismatched]
                + self.cell_sums)


@dataclass(frozen=True)
class PackSettings:
    """The ``pack.*`` values (devices/generated_configs.py builds them from the parameters)."""

    members: tuple[str, ...]
    connection: str = PARALLEL
    limits: Mapping[str, Sequence[float]] = field(default_factory=dict)
    debounce: float = 0.5
    max_charge_current: float = 0.0  # A; 0: not configured, the limit is NaN
    max_discharge_current: float = 0.0
    time_window: float = 60.0
    max_voltage_difference: float = 1.5
    max_cell_sum_difference: float = 3.0


class Pack:
    """One battery from several devices' reports."""

    def __init__(self, settings: PackSettings) -> None:
        """Start with no report: everything unknown, nothing raised."""
        self.settings = settings
        self.limits = Limits(dict(settings.limits), settings.debounce)
        self.time_to_go = TimeToGo(settings.time_window)
        self.last: PackOutput | None = None
        self._lock = threading.Lock()  # the bus thread updates, a service clears

    def update(self, members: Members, stamp: float) -> PackOutput:
        """Take every member's latest report (in member order) at ``stamp``."""
        s = self.settings
        with self._lock:
            report = aggregate(members, s.connection)
            stale = [name for name, r in members if not r.present]
            mismatched = (voltage_mismatch_pairs(members, s.max_voltage_difference)
                          if s.connection == PARALLEL else [])
            cell_sums = cell_sum_mismatches(members, s.max_cell_sum_difference)
            raised = self.limits.update(report, stamp)
            value = self.limits.value
            charge = derated(s.max_charge_current, CHARGE_INPUTS, s.limits, value)
            discharge = derated(s.max_discharge_current, DISCHARGE_INPUTS, s.limits, value)
            if stale or self.limits.latched:
                # fail-safe: a pack with a silent member or past its safety limit allows nothing
                charge = 0.0 if not math.isnan(charge) else charge
                discharge = 0.0 if not math.isnan(discharge) else discharge
            self.time_to_go.add(stamp, report.current)
            empty, full = self.time_to_go.times(report.charge, report.capacity)
            self.last = PackOutput(report, charge, discharge, empty, full, raised, stale,
                                   mismatched, s.max_voltage_difference, cell_sums)
            return self.last

    def clear_events(self) -> tuple[bool, str]:
        """Clear the latched MSL events back inside; ``(False, what is still beyond)``."""
        with self._lock:
            return self.limits.clear()

    def diagnostic_report(self) -> DiagnosticReport:
        """Return the pack's status: warnings, events with when raised and the worst value."""
        with self._lock:
            last = self.last
            events = sorted(self.limits.events.values(), key=lambda e: (e.limit, e.severity))
            worst = self.limits.worst_severity()
        values: dict[str, str] = {'members': ', '.join(self.settings.members),
                                  'connection': self.settings.connection}
        if last is None:
            return DiagnosticReport(Level.STALE, 'no member report yet', values)
        level = Level.OK
        parts = list(last.warnings)
        if parts:
            level = Level.WARN
        if worst is Severity.MSL:
            level = Level.ERROR
        elif worst is Severity.RSL:
            level = max(level, Level.WARN)
        if not last.report.present:
            level = Level.STALE
        for event in events:
            key = f'event {event.severity.name} {event.limit}'
            values[key] = (f'raised at {event.raised_at:.3f}, worst {event.worst:g}, '
                           f'level {event.level:g}')
            parts.append(event.describe())
        values.update({
            'charge_current_limit': f'{last.charge_current_limit:g}',
            'discharge_current_limit': f'{last.discharge_current_limit:g}',
            'time_to_empty': f'{last.time_to_empty:g}',
            'time_to_full': f'{last.time_to_full:g}',
            'voltage': f'{last.report.voltage:g}', 'current': f'{last.report.current:g}',
        })
        message = '; '.join(parts) if parts else 'OK'
        return DiagnosticReport(level, message, values)
