# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``pack`` device type: a Device without frames, fed by the engine with member reports.

It reads no CAN ID and sends none; DeviceSet gives it its members (``attach_members``), the
engine hands it each member report it emits (``take``) and emits what comes back. Its one
service, ``clear_events``, answers from here and sends nothing (commands.py ``LOCAL``).
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Mapping, Sequence

from ams_can_bridge.devices.base import (BatteryReport, Device, DiagnosticReport, Level,
                                         stale_report)
from ams_can_bridge.devices.commands import Command, LOCAL, TRIGGER
from ams_can_bridge.devices.generated_configs import PackConfig
from ams_can_bridge.devices.pack.aggregate import CONNECTIONS, PARALLEL
from ams_can_bridge.devices.pack.core import Pack, PackOutput, PackSettings
from ams_can_bridge.devices.pack.limits import check_levels, KINDS
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.parameters import MAX_DEVICES, ParamSpec

# The std_msgs/Float32 topics '<pack>/<figure>', in this order.
FIGURES = ('charge_current_limit', 'discharge_current_limit', 'time_to_empty', 'time_to_full')
# Types that report no battery of their own (a current sensor, another pack).
NOT_BATTERIES = frozenset({'ivt_s', 'pack'})
LIMIT_HELP = {
    'cell_voltage_max': 'highest cell voltage [V]',
    'cell_voltage_min': 'lowest cell voltage [V]',
    'temperature_max': 'highest temperature [degC]',
    'temperature_min': 'lowest temperature [degC]',
    'charge_current_max': 'charge current [A, positive]',
    'discharge_current_max': 'discharge current [A, positive]',
}


def _limit_spec(name: str) -> ParamSpec:
    direction = 'increasing' if KINDS[name].upper else 'decreasing'
    return ParamSpec(f'limits.{name}', 'float[]', [],
                     f'[MOL, RSL, MSL] of the {LIMIT_HELP[name]}, strictly {direction}; '
                     '[] = not watched', max_length=3)


class PackDevice(Device[PackConfig]):
    """One battery from several battery devices of the node (doc/packs.md)."""

    TYPE = 'pack'
    BROADCAST_PERIOD = 1.0  # its own stale_timeout is unused: stale = every member stale
    Config = PackConfig
    FIGURES = FIGURES
    PARAMS = [
        ParamSpec('members', 'str[]', None, 'battery instances combined, listed before the '
                  'pack in devices', max_length=MAX_DEVICES),
        ParamSpec('connection', str, PARALLEL, 'how the members are wired: parallel (voltage '
                  'mean, currents summed) or series (voltages summed)', choices=CONNECTIONS),
        *[_limit_spec(name) for name in KINDS],
        ParamSpec('limits.debounce', float, 0.5, 's a value stays beyond a level before its '
                  'event is raised', low=0.0, high=60.0),
        ParamSpec('max_charge_current', float, 0.0, 'A the pack may be charged with inside '
                  'MOL (0 = unknown: charge_current_limit NaN)', low=0.0, high=100000.0),
        ParamSpec('max_discharge_current', float, 0.0, 'A the pack may deliver inside MOL '
                  '(0 = unknown: discharge_current_limit NaN)', low=0.0, high=100000.0),
        ParamSpec('time_window', float, 60.0, 's of mean current behind time_to_empty and '
                  'time_to_full', low=1.0, high=3600.0),
        ParamSpec('max_voltage_difference', float, 1.5, 'V parallel members may differ before '
                  'a WARN naming both', low=0.0, high=10000.0),
        ParamSpec('max_cell_sum_difference', float, 3.0, "V a member's cell sum may differ "
                  'from its measured voltage before a WARN', low=0.0, high=10000.0),
    ]
    COMMANDS = (Command('clear_events', 'clear the latched MSL events', TRIGGER,
                        'clear_events', LOCAL),)

    def __init__(self, name: str, config: PackConfig | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Check the configuration; the members come later (attach_members)."""
        super().__init__(name, config, clock)
        self.members: list[Device[Any]] = []
        self.pack = Pack(self.settings(self.config))
        self._reports: dict[str, BatteryReport] = {}
        self._updates = 0

    def config_problems(self, config: PackConfig,
                        keys: Sequence[str] | Any = None) -> list[str]:
        """Name a missing member list and every limit list that is not [MOL, RSL, MSL]."""
        problems = []
        if not config.members:
            problems.append(f'{self.name}.members is empty: list the battery instances this '
                            'pack combines')
        for name in KINDS:
            levels = config.value(f'limits.{name}') or ()
            if levels:
                problem = check_levels(name, levels)
                if problem:
                    problems.append(f'{self.name}.{problem}')
        return problems

    def settings(self, config: PackConfig) -> PackSettings:
        """Return the core's settings from the parameters."""
        limits = {name: tuple(config.value(f'limits.{name}')) for name in KINDS
                  if config.value(f'limits.{name}')}
        return PackSettings(
            tuple(config.members or ()), config.connection, limits, config.limits_debounce,
            config.max_charge_current, config.max_discharge_current, config.time_window,
            config.max_voltage_difference, config.max_cell_sum_difference)

    def _reconfigured(self, old: PackConfig, new: PackConfig) -> None:
        # parameters are read-only at run time (ParamSpec default): nothing to follow
        pass

    def attach_members(self, devices: Mapping[str, Device[Any]]) -> None:
        """Take the member instances; ConfigError naming what to change in ``members``."""
        names = list(devices)
        own = names.index(self.name)
        members = list(self.config.members or ())
        for member in members:
            where = f'{self.name}.members: {member!r}'
            if member == self.name:
                raise ConfigError(f'{where} is the pack itself: list its battery instances')
            if members.count(member) > 1:
                raise ConfigError(f'{where} is listed twice: list each member once')
            if member not in devices:
                raise ConfigError(f'{where} is not in devices (devices lists '
                                  f'{", ".join(names)}): add it or remove it from the pack')
            if devices[member].TYPE in NOT_BATTERIES:
                raise ConfigError(f'{where} is of type {devices[member].TYPE}, not a battery: '
                                  'list battery instances (ams, evms3, bms16, sma, dbc)')
            if names.index(member) > own:
                raise ConfigError(f'{where} comes after {self.name} in devices: list the '
                                  'members before the pack')
        self.members = [devices[m] for m in members]

    # --- no frames ------------------------------------------------------------------------
    @property
    def arbitration_ids(self) -> frozenset[int]:
        """Return no ID: a pack reads its members' reports, never frames."""
        return frozenset()

    @property
    def is_extended_id(self) -> bool:
        """Tell False: a pack has no IDs."""
        return False

    def handle_frame(self, arbitration_id: int, data: bytes, stamp: float) -> bool:
        """Take no frame (DeviceSet never gives it one)."""
        return False

    # --- fed by the engine --------------------------------------------------------------
    def take(self, member: str, report: BatteryReport, stamp: float) -> PackOutput:
        """Take a member's report (emitted at ``stamp``); return the pack's output."""
        self._reports[member] = report
        members = []
        for device in self.members:
            last = self._reports.get(device.name) or BatteryReport()
            # a member silent since its last report counts as stale now, not at its next
            # stale message (up to a second later)
            if last.present and device.is_stale():
                last = stale_report(last)
            members.append((device.name, last))
        out = self.pack.update(members, stamp)
        config = self.config
        out.report.location = config.location
        out.report.serial_number = config.serial_number
        if not math.isfinite(out.report.stamp):
            out.report.stamp = stamp
        self._updates += 1
        if out.report.present:
            self.last_seen = self.clock()
        return out

    @staticmethod
    def figures(out: PackOutput) -> dict[str, float]:
        """Return the Float32 topics' values of one output, by FIGURES suffix."""
        return {'charge_current_limit': out.charge_current_limit,
                'discharge_current_limit': out.discharge_current_limit,
                'time_to_empty': out.time_to_empty, 'time_to_full': out.time_to_full}

    def clear_events(self) -> tuple[bool, str]:
        """Clear the latched MSL events back inside (the clear_events service)."""
        ok, message = self.pack.clear_events()
        self._updates += 1  # the level may change: the engine's watch looks again
        return ok, f'{self.name}: {message}'

    # --- reports ------------------------------------------------------------------------------
    @property
    def revision(self) -> int:
        """Count updates and configuration changes."""
        return self._updates + self._config_changes

    def is_stale(self) -> bool:
        """Tell whether every member is stale (one present member keeps the pack present)."""
        return all(m.is_stale() for m in self.members)

    def snapshot(self) -> tuple[BatteryReport, dict[str, tuple[int, int, list[float]]]]:
        """Return the last pack report (stale: present False, NaN) and no arrays."""
        last = self.pack.last
        report = last.report if last is not None else BatteryReport()
        if self.is_stale():
            report = stale_report(report)
            report.location = self.config.location
            report.serial_number = self.config.serial_number
        return report, {}

    def battery_report(self) -> BatteryReport:
        """Return the last pack report."""
        return self.snapshot()[0]

    def diagnostic_report(self) -> DiagnosticReport:
        """Return the pack's status: warnings, events (when raised, worst value), limits."""
        report = self.pack.diagnostic_report()
        if self.members and self.is_stale():
            report.level = Level.STALE
            report.message = 'stale: every member is silent'
        return report

    def diagnostic_level(self) -> Level:
        """Return the level diagnostic_report() gives."""
        return self.diagnostic_report().level
