"""
The checked form of a dbc device's mapping (``Plan``) and the tables it is checked with.

``devices.dbc_mapping`` builds a Plan from a DBC and a mapping file; ``devices.dbc`` and
``sim.dbc`` use it. docs/protocols.md section 8 lists the units and the rules.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ams_can_bridge.devices.base import (
    Level, PowerSupplyHealth, PowerSupplyStatus, PowerSupplyTechnology)
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols import dbc_codec
from ams_can_bridge.protocols.common import msg_defs_dir

# BatteryState field -> the unit it wants (None: an enum or a name, not a number).
SCALAR_UNITS = {'voltage': 'V', 'current': 'A', 'charge': 'Ah', 'capacity': 'Ah',
                'design_capacity': 'Ah', 'percentage': 'fraction', 'temperature': 'degC'}
ARRAY_UNITS = {'cell_voltage': 'V', 'cell_temperature': 'degC'}
ENUMS: dict[str, Any] = {'power_supply_status': PowerSupplyStatus,
                         'power_supply_health': PowerSupplyHealth,
                         'power_supply_technology': PowerSupplyTechnology}
# DBC unit -> (factor, offset) to the wanted unit: wanted = value * factor + offset.
_CELSIUS = {u: (1.0, 0.0) for u in (
    'degC', '°C', 'C', 'deg C', 'degree C', 'Celsius', 'celsius', 'DegC', '\u2103')}
CONVERSIONS: dict[str, dict[str, tuple[float, float]]] = {
    'V': {'V': (1.0, 0.0), 'mV': (1e-3, 0.0), 'kV': (1e3, 0.0), 'uV': (1e-6, 0.0),
          'µV': (1e-6, 0.0), 'dV': (0.1, 0.0), 'cV': (0.01, 0.0)},
    'A': {'A': (1.0, 0.0), 'mA': (1e-3, 0.0), 'kA': (1e3, 0.0), 'uA': (1e-6, 0.0),
          'µA': (1e-6, 0.0), 'dA': (0.1, 0.0), 'cA': (0.01, 0.0)},
    'Ah': {'Ah': (1.0, 0.0), 'mAh': (1e-3, 0.0), 'kAh': (1e3, 0.0), 'As': (1 / 3600, 0.0),
           'mAs': (1 / 3.6e6, 0.0)},
    'degC': {**_CELSIUS, 'K': (1.0, -273.15), 'degF': (5 / 9, -160 / 9),
             '°F': (5 / 9, -160 / 9), 'dK': (0.1, -273.15)},
    'fraction': {'%': (0.01, 0.0), 'percent': (0.01, 0.0), '‰': (0.001, 0.0)},
}
REDUCERS = ('sum', 'max', 'min', 'mean')
CONDITIONS = ('equal', 'not_equal', 'below', 'above')
TOP_LEVEL = ('primary', 'battery_state', 'diagnostics', 'timeouts')
LEVELS = {'OK': Level.OK, 'WARN': Level.WARN, 'ERROR': Level.ERROR}


def unit_text(unit: str) -> str:
    """
    Return a DBC unit as its author wrote it.

    cantools reads DBC files as cp1252 (the usual encoding of CANdb++ files), so a UTF-8
    file's '°C' arrives as 'Â°C'; both mean degC.
    """
    text = unit.strip()
    try:
        return text.encode('cp1252').decode('utf-8')
    except UnicodeError:
        return text


class MappingError(ConfigError):
    """The DBC or the mapping cannot be used: every problem, one per line."""


@dataclass(frozen=True)
class Ref:
    """One DBC signal, and how its physical value becomes the wanted unit."""

    message: int  # index into Plan.messages
    signal: int  # index into that message's decoded tuple
    mux: tuple[int, ...] | None  # multiplexer values of its branch (None: every frame)
    name: str  # 'Message.signal'
    unit: str
    factor: float = 1.0
    add: float = 0.0


@dataclass(frozen=True)
class Scalar:
    """A BatteryState number: a constant, a signal, or a reduction of an array."""

    constant: float | None = None
    ref: Ref | None = None
    reduce: str = ''  # 'sum' | 'max' | 'min' | 'mean' of the array 'of'
    of: str = ''
    fallback: 'Scalar | None' = None


@dataclass(frozen=True)
class EnumRule:
    """A signal's value -> an enum value; ``otherwise`` for every other known value."""

    ref: Ref
    table: dict[float, int]
    otherwise: int | None


@dataclass(frozen=True)
class Enum:
    """A BatteryState enum: a constant, or rules tried in order (first answer wins)."""

    constant: int | None = None
    rules: tuple[EnumRule, ...] = ()


@dataclass(frozen=True)
class Array:
    """
    cell_voltage / cell_temperature.

    Template form: one Ref per element (and its invalid flag). Slot form: one message
    carries ``per_frame`` elements at a position its selector signals give
    (``sum((selector - first) * stride)``), as the AMS sends its banks and groups.
    """

    count: int
    refs: tuple[Ref, ...] = ()
    invalid: tuple[Ref | None, ...] = ()
    slot_message: int | None = None
    slot_signals: tuple[int, ...] = ()
    selectors: tuple[tuple[int, float, int], ...] = ()  # (signal index, first, stride)
    factor: float = 1.0
    add: float = 0.0


@dataclass(frozen=True)
class LevelRule:
    """diagnostics.levels: a condition on a signal -> a level and a message."""

    ref: Ref
    condition: str
    threshold: float
    level: Level
    message: str


@dataclass
class Plan:
    """A validated mapping, ready for the device."""

    messages: list[dbc_codec.CompiledMessage]
    primary: int
    scalars: dict[str, Scalar] = field(default_factory=dict)
    enums: dict[str, Enum] = field(default_factory=dict)
    arrays: dict[str, Array] = field(default_factory=dict)
    levels: list[LevelRule] = field(default_factory=list)
    values: list[Ref] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    timeouts: dict[int, float] = field(default_factory=dict)  # message -> s (else stale_timeout)


def resolve_path(path: str) -> Path:
    """
    Find a DBC or mapping file.

    As given (absolute, or relative to the working directory), else relative to the
    installed package's share folder (``msg_defs/ams.dbc``,
    ``config/ams_dbc_mapping.yaml`` work from anywhere).
    """
    given = Path(os.path.expanduser(path))
    if given.is_absolute() or given.exists():
        return given
    try:
        shared = msg_defs_dir().parent / given
    except FileNotFoundError:
        return given
    return shared if shared.exists() else given
