# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Safe operating area in three levels (foxBMS 2): MOL info, RSL warning, MSL fatal.

Each limit is a list ``[MOL, RSL, MSL]``. A level is raised when its value stays beyond it for
the debounce time (a single noisy report raises nothing); MOL and RSL fall as soon as the value
is back inside; MSL stays latched until ``clear`` is called while the value is back inside, so
a supervisor that looks late still sees that the pack went beyond its maximum safe limit.
An unknown value (NaN) neither raises nor clears: nothing was measured.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

from ams_can_bridge.devices.base import BatteryReport


class Severity(enum.IntEnum):
    """The three levels, in list order."""

    MOL = 0  # maximum operating limit: noted
    RSL = 1  # recommended safety limit: WARN
    MSL = 2  # maximum safety limit: ERROR, latched


SEVERITIES = tuple(Severity)  # iterating the enum class itself costs a call per update


@dataclass(frozen=True)
class LimitKind:
    """A limit's value in a pack report and its direction (above or below is beyond)."""

    unit: str
    upper: bool  # beyond = above the level; False: below


# The limit names of doc/packs.md (``pack.limits.<name>``).
KINDS: dict[str, LimitKind] = {
    'cell_voltage_max': LimitKind('V', True),
    'cell_voltage_min': LimitKind('V', False),
    'temperature_max': LimitKind('degC', True),
    'temperature_min': LimitKind('degC', False),
    'charge_current_max': LimitKind('A', True),
    'discharge_current_max': LimitKind('A', True),
}


def limit_value(name: str, report: BatteryReport) -> float:
    """Return the pack value a limit watches (NaN when unknown)."""
    return limit_values(report, (name,))[name]


def limit_values(report: BatteryReport, names: Iterable[str]) -> dict[str, float]:
    """
    Return the pack values the limits watch, by name (NaN when unknown).

    Each array is checked once for all the limits that watch it (at every member report:
    the cells of every member), and the temperature is not copied onto the cell temperatures:
    the highest (lowest) of ``temperature`` and every cell temperature, NaN when one is unknown;
    with no cell temperature, ``temperature`` alone.
    """
    out = {}
    cells_known: bool | None = None
    temps_known: bool | None = None
    temps = report.cell_temperature
    temperature = report.temperature
    for name in names:
        upper = KINDS[name].upper
        if name.startswith('cell_voltage'):
            if cells_known is None:
                cells = report.cell_voltage
                cells_known = bool(cells) and math.isfinite(sum(cells))
            out[name] = ((max(cells) if upper else min(cells)) if cells_known else math.nan)
        elif name.startswith('temperature'):
            if temps_known is None:
                # the sum of the cells' and then the pack's (when known): _extreme's check
                total = sum(temps) if temps else 0.0
                own = math.isfinite(temperature)
                temps_known = math.isfinite(total + temperature if own or not temps else total)
            if not temps_known:
                out[name] = math.nan
            elif not temps:
                out[name] = temperature
            else:
                extreme = max(temps) if upper else min(temps)
                if math.isfinite(temperature):
                    extreme = max(extreme, temperature) if upper else min(extreme, temperature)
                out[name] = extreme
        elif name == 'charge_current_max':
            out[name] = report.current  # ROS sign: positive while charging
        else:
            out[name] = -report.current  # discharge current, positive
    return out


def check_levels(name: str, levels: Sequence[float]) -> str | None:
    """Return why a ``[MOL, RSL, MSL]`` list is wrong, or None."""
    if len(levels) != 3 or not all(math.isfinite(v) for v in levels):
        return f'pack.limits.{name} must be three numbers [MOL, RSL, MSL], got {list(levels)}'
    upper = KINDS[name].upper
    ordered = levels[0] < levels[1] < levels[2] if upper else levels[0] > levels[1] > levels[2]
    if not ordered:
        word = 'increasing' if upper else 'decreasing'
        return (f'pack.limits.{name} must be strictly {word} [MOL, RSL, MSL] '
                f'(a {"maximum" if upper else "minimum"}), got {list(levels)}')
    return None


def beyond(name: str, value: float, level: float) -> bool:
    """Return whether a known value is beyond a level of the limit."""
    return value > level if KINDS[name].upper else value < level


@dataclass
class Event:
    """A raised level: when, and the worst value seen while it was raised."""

    limit: str
    severity: Severity
    level: float
    raised_at: float
    worst: float

    def describe(self) -> str:
        """Return a one-line description for diagnostics and logs."""
        unit = KINDS[self.limit].unit
        return (f'{self.severity.name} {self.limit}: beyond {self.level:g} {unit} '
                f'since {self.raised_at:.3f}, worst {self.worst:g} {unit}')


@dataclass
class Limits:
    """The events of one pack: debounce, raise, fall, latch, clear."""

    levels: Mapping[str, Sequence[float]]
    debounce: float = 0.5
    events: dict[tuple[str, Severity], Event] = field(default_factory=dict)
    _since: dict[tuple[str, Severity], float] = field(default_factory=dict)
    _values: dict[str, float] = field(default_factory=dict)
    # limits with a level counting or raised: the others are skipped while inside MOL
    _open: set[str] = field(default_factory=set)

    def value(self, name: str) -> float:
        """Return the value of a watched limit at the last update (NaN: unknown or none)."""
        return self._values.get(name, math.nan)

    def update(self, report: BatteryReport, stamp: float) -> list[Event]:
        """Take a pack report at ``stamp``; return the events raised by it."""
        raised = []
        self._values = values = limit_values(report, self.levels)
        for name, levels in self.levels.items():
            value = values[name]
            if math.isnan(value):
                continue
            if name not in self._open and not beyond(name, value, levels[0]):
                continue  # inside MOL, nothing counting: the common case, one comparison
            for severity in SEVERITIES:
                key = (name, severity)
                event = self.events.get(key)
                if beyond(name, value, levels[severity]):
                    since = self._since.setdefault(key, stamp)
                    if event is not None:
                        if beyond(name, value, event.worst):
                            event.worst = value
                    elif stamp - since >= self.debounce:
                        event = Event(name, severity, levels[severity], stamp, value)
                        self.events[key] = event
                        raised.append(event)
                else:
                    self._since.pop(key, None)
                    if event is not None and severity is not Severity.MSL:
                        del self.events[key]
            if any((name, s) in self._since or (name, s) in self.events for s in SEVERITIES):
                self._open.add(name)
            else:
                self._open.discard(name)
        return raised

    @property
    def latched(self) -> bool:
        """Return whether an MSL event is latched."""
        return any(key[1] is Severity.MSL for key in self.events)

    def worst_severity(self) -> Severity | None:
        """Return the highest raised level, None when nothing is raised."""
        return max((key[1] for key in self.events), default=None)

    def clear(self) -> tuple[bool, str]:
        """
        Clear the latched MSL events whose value is back inside; name those still beyond.

        A value that is unknown now counts as still beyond: nothing shows it is back inside.
        """
        still = []
        cleared = []
        for key, event in sorted(self.events.items()):
            if key[1] is not Severity.MSL:
                continue
            value = self._values.get(event.limit, math.nan)
            if math.isnan(value) or beyond(event.limit, value, event.level):
                unit = KINDS[event.limit].unit
                still.append(f'{event.limit} is {value:g} {unit}, beyond the MSL '
                             f'{event.level:g} {unit}')
            else:
                del self.events[key]
                cleared.append(event.limit)
        if still:
            done = f' (cleared: {", ".join(cleared)})' if cleared else ''
            return False, 'still beyond: ' + '; '.join(still) + done
        if cleared:
            return True, 'cleared: ' + ', '.join(cleared)
        return True, 'no latched event'
