# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The checked form of a dbc device's mapping (``Plan``) and the tables it is checked with.

``devices.dbc.mapping`` builds a Plan from a DBC and a mapping file; ``devices.dbc.device`` and
``sim.dbc`` use it. doc/protocols.md section 8 lists the units and the rules.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from ams_can_bridge.protocols.battery_state import (
    Level, PowerSupplyHealth, PowerSupplyStatus, PowerSupplyTechnology)
from ams_can_bridge.protocols.dbc_mapping.units import BASE
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols import dbc_codec
from ams_can_bridge.protocols.common import CELL_V_MAX, msg_defs_dir, TEMP_C_MAX

# BatteryState field -> the quantity it wants (dbc_units; None: an enum or a name).
SCALAR_UNITS = {'voltage': 'V', 'current': 'A', 'charge': 'Ah', 'capacity': 'Ah',
                'design_capacity': 'Ah', 'percentage': 'fraction', 'temperature': 'degC'}
ARRAY_UNITS = {'cell_voltage': 'V', 'cell_temperature': 'degC'}
ARRAY_LABELS = {'cell_voltage': 'cell voltages', 'cell_temperature': 'cell temperatures'}
ENUMS: dict[str, Any] = {'power_supply_status': PowerSupplyStatus,
                         'power_supply_health': PowerSupplyHealth,
                         'power_supply_technology': PowerSupplyTechnology}
REDUCERS = ('sum', 'max', 'min', 'mean')
CONDITIONS = ('equal', 'not_equal', 'below', 'above', 'any_bits', 'all_bits')
CONDITION_TEXT = {'equal': '=', 'not_equal': '!=', 'below': '<', 'above': '>',
                  'any_bits': 'has any of the bits', 'all_bits': 'has all of the bits'}
TOP_LEVEL = ('primary', 'battery_state', 'diagnostics', 'timeouts')
LEVELS = {'OK': Level.OK, 'WARN': Level.WARN, 'ERROR': Level.ERROR}
# A message's own timeout from its DBC period: this many periods (of a whole rotation for a
# multiplexed message), never shorter than MIN_TIMEOUT (a loaded host delivers late).
TIMEOUT_PERIODS = 5
MIN_TIMEOUT = 0.1  # s
# ... and never below LEARNED_PERIODS x the period it is heard at (a vendor's utility may set
# a slower rate than its DBC says); an interval OUTLIER x the period so far is a pause, not a
# new rate (devices.dbc.device DbcDevice._learn).
LEARNED_PERIODS = 3
OUTLIER = 4.0


# What no battery reports, in each field's unit (doc/protocols.md "Physical bounds", section
# 8): a mapped signal's value beyond its field's bounds is implausible, its frame malformed,
# whatever the DBC's [min|max] allows. The built-in devices' bounds (cells, temperatures,
# no negative pack voltage), and what a dbc field can be wrong by on top: a DBC read with the
# wrong layout or unit gives values no battery has.
PACK_V_MAX = 1500.0  # V: the top of low voltage (DC); no battery pack of a vehicle is above
CURRENT_A_MAX = 4000.0  # A: beyond the largest shunt (IVT-S: 2500 A) and any pack's fuse
CHARGE_AH_MAX = 100000.0  # Ah: 100 kAh (a 48 V, 5 MWh storage); a counter may be negative
COLDEST_C = -90.0  # degC: colder than any air on Earth's surface (-89.2 degC, Vostok 1983)
FIELD_BOUNDS = {'voltage': (0.0, PACK_V_MAX), 'current': (-CURRENT_A_MAX, CURRENT_A_MAX),
                'charge': (-CHARGE_AH_MAX, CHARGE_AH_MAX), 'capacity': (0.0, CHARGE_AH_MAX),
                'design_capacity': (0.0, CHARGE_AH_MAX), 'percentage': (0.0, 1.0),
                'temperature': (COLDEST_C, TEMP_C_MAX), 'cell_voltage': (0.0, CELL_V_MAX),
                'cell_temperature': (COLDEST_C, TEMP_C_MAX)}


class MappingError(ConfigError):
    """The DBC or the mapping cannot be used: every problem, one per line."""


@dataclass(frozen=True)
class Ref:
    """One DBC signal, and how its physical value becomes the wanted unit."""

    message: int  # index into Plan.messages
    signal: int  # index into that message's decoded tuple
    mux: tuple[int, ...] | None  # multiplexer values of its branch (None: every frame)
    name: str  # 'Message.signal'
    unit: str  # as the DBC spells it (or the mapping's unit:)
    factor: float = 1.0  # wanted = DBC value * factor + add
    add: float = 0.0
    # how factor and add came about, for the start log
    converted: str = ''  # 'mV' when the unit was converted, '' when taken as it is
    scale: float = 1.0  # the mapping's scale and offset, after the unit's conversion
    offset: float = 0.0


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
class FlagRule:
    """What a validity flag's value means: invalid when it is (or is not) one of values."""

    values: frozenset[float]
    invalid_if_in: bool  # True: invalid when the flag is one of values; False: unless it is
    why: str  # for the start log: 'the DBC value table names 0 "Invalid"', ...

    def invalid(self, value: float | None) -> bool:
        """Tell whether a flag value means "no data" (unknown counts as invalid)."""
        if value is None or value != value:
            return True
        return (value in self.values) == self.invalid_if_in

    def text(self, template: str) -> str:
        """Say the rule: 'invalid when Msg.flag_{i} = 0 (why)'."""
        values = ' or '.join(f'{v:g}' for v in sorted(self.values))
        sign = '=' if self.invalid_if_in else '!='
        return f'invalid when {template} {sign} {values} ({self.why})'


@dataclass(frozen=True)
class Array:
    """
    cell_voltage / cell_temperature.

    Template form: one Ref per element (and its validity flag). Slot form: one message
    carries ``per_frame`` elements at a position its selector signals give
    (``sum((selector - first) * stride)``), as the AMS sends its banks and groups.
    """

    count: int
    refs: tuple[Ref, ...] = ()
    invalid: tuple[Ref | None, ...] = ()
    flag_rule: FlagRule | None = None
    slot_message: int | None = None
    slot_signals: tuple[int, ...] = ()
    selectors: tuple[tuple[int, float, int], ...] = ()  # (signal index, first, stride)
    factor: float = 1.0
    add: float = 0.0
    # for the start log: the mapping's template or list, its first element's conversion
    source: str = ''
    flag_source: str = ''
    sample: Ref | None = None


@dataclass(frozen=True)
class LevelRule:
    """diagnostics.levels: a condition on a signal -> a level and a message."""

    ref: Ref
    condition: str  # one of CONDITIONS
    threshold: float  # in the signal's DBC unit; a bit mask for any_bits / all_bits
    level: Level
    message: str

    def hit(self, value: float, info: dbc_codec.SignalInfo) -> bool:
        """Tell whether the DBC value meets the condition."""
        condition = self.condition
        if condition == 'below':
            return value < self.threshold
        if condition == 'above':
            return value > self.threshold
        if condition == 'equal':
            return value == self.threshold
        if condition == 'not_equal':
            return value != self.threshold
        mask = int(self.threshold)
        bits = round((value - info.offset) / info.scale) & mask  # the raw value's bits
        return bits == mask if condition == 'all_bits' else bits != 0


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
    warnings: list[str] = field(default_factory=list)  # the mapping's
    dbc_notes: list[str] = field(default_factory=list)  # lines dropped, broken messages
    dbc_info: list[str] = field(default_factory=list)  # the encoding, CANdb++'s placeholder
    # message -> s, from the mapping's timeouts or the DBC's period (else stale_timeout)
    timeouts: dict[int, float] = field(default_factory=dict)
    timeout_origin: dict[int, str] = field(default_factory=dict)  # message -> why
    mapped: frozenset[tuple[int, int]] = frozenset()  # (message, signal) any rule reads
    files: tuple[str, str] = ('', '')  # the DBC and the mapping as found
    sources: list[Any] = field(default_factory=list)  # the cantools message of each message
    # (message, signal) -> what the field it is mapped to can be (FIELD_BOUNDS) as the
    # start log and a refused frame say it: 'percentage 0..1'
    bounds: dict[tuple[int, int], str] = field(default_factory=dict)


def base_unit(quantity: str) -> str:
    """Return how the start log writes a quantity's unit ('V', '0..1', ...)."""
    return BASE.get(quantity, quantity)


# --- where the files are ----------------------------------------------------------------
_params_folders: list[Path] = []


def set_params_files(paths: Iterable[str]) -> None:
    """
    Say which params files the process was given (--params-file): their folders are searched.

    The bridge and log2bag call it with their command line; a relative dbc_file or
    mapping_file is then also found beside the params file that names it.
    """
    _params_folders[:] = [Path(os.path.expanduser(p)).resolve().parent for p in paths]


def locate(path: str) -> tuple[Path | None, list[Path]]:
    """
    Find a DBC or mapping file; return it (None: not found) and every place looked at.

    Absolute: itself. Relative: the working directory, the folder of each params file the
    process was given, then the installed package's share folder (``msg_defs/ams.dbc``,
    ``config/ams_dbc_mapping.yaml`` work from anywhere).
    """
    given = Path(os.path.expanduser(path))
    if given.is_absolute():  # a FIFO or directory is found too: the caller says what it is
        return (given if given.exists() else None), [given]
    places = [Path.cwd() / given] + [folder / given for folder in _params_folders]
    try:
        places.append(msg_defs_dir().parent / given)
    except FileNotFoundError:
        pass
    for place in places:
        if place.exists():
            return place, places
    return None, places


def resolve_path(path: str) -> Path:
    """Return the file locate() finds, else the path as given (for an error to name)."""
    found, _ = locate(path)
    return found if found is not None else Path(os.path.expanduser(path))
