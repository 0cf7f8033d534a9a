# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The mapping of a ``dbc`` device: a team's DBC signals -> BatteryState fields and diagnostics.

doc/own_bms.md documents the file; doc/protocols.md section 8 the decisions. Loading
checks everything at once and raises ``MappingError`` listing every problem (the bridge
stops with exit 2): each referenced message and signal must exist (the error names the
closest names) and be usable (not in a broken message, not a duplicated name), the primary
must be set, array templates must resolve, map keys must be value names (VAL_) or numbers.
Units come from the DBC and are converted to what BatteryState wants (``dbc_units``).

This module finds and reads the two files and walks the mapping's structure; the checks of
each entry are ``devices.dbc.builder``'s and ``devices.dbc.arrays``'.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterable

import yaml

from ams_can_bridge.protocols.dbc_mapping.arrays import build_array
from ams_can_bridge.protocols.dbc_mapping.builder import Builder
from ams_can_bridge.protocols.dbc_mapping.plan import (
    Array, ARRAY_UNITS, base_unit, Enum, ENUMS, FIELD_BOUNDS, locate, MappingError,
    MIN_TIMEOUT, Plan, Ref, Scalar, SCALAR_UNITS, TIMEOUT_PERIODS, TOP_LEVEL)
from ams_can_bridge.protocols.dbc_profiles import profile_files
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.input_files import file_problem, load_yaml
from ams_can_bridge.protocols import dbc_codec
from ams_can_bridge.protocols.dbc_load import cycle_time, DbcLoadError, LoadedDbc, read_dbc


def build_plan(loaded: LoadedDbc, mapping: Any) -> Plan:
    """Check a loaded mapping against a loaded DBC; MappingError lists every problem."""
    if not isinstance(mapping, dict):
        raise MappingError('the mapping file is not a YAML mapping (primary:, battery_state:)')
    b = Builder(loaded, mapping)
    for key in mapping:
        if key not in TOP_LEVEL:
            b.problems.append(f'unknown top-level key {key!r}' + dbc_codec.closest(
                str(key), list(TOP_LEVEL)))
    primary = None
    if not mapping.get('primary'):
        b.problems.append('primary is not set: name the message that makes one BatteryState '
                          'per frame (primary: <Message>)')
    else:
        primary = b.message(str(mapping['primary']), 'primary')
    plan_parts: dict[str, dict] = {'scalars': {}, 'enums': {}, 'arrays': {}}
    state = mapping.get('battery_state') or {}
    if not isinstance(state, dict):
        b.problems.append('battery_state: write {field: source}')
        state = {}
    result: Scalar | Enum | Array | None
    for key, spec in state.items():
        where = f'battery_state.{key}'
        if key in SCALAR_UNITS:
            result, part = b.scalar(key, spec, where), 'scalars'
        elif key in ENUMS:
            result, part = b.enum(key, spec, where), 'enums'
        elif key in ARRAY_UNITS:
            result, part = build_array(b, key, spec, where), 'arrays'
        else:
            b.problems.append(f'{where}: not a BatteryState field we fill' + dbc_codec.closest(
                str(key), [*SCALAR_UNITS, *ENUMS, *ARRAY_UNITS]))
            continue
        if result is not None:
            plan_parts[part][key] = result
    for key, scalar in plan_parts['scalars'].items():
        if scalar.reduce and scalar.of not in plan_parts['arrays']:
            b.problems.append(f'battery_state.{key}: reduces {scalar.of}, which is not mapped')
    diagnostics = mapping.get('diagnostics') or {}
    if not isinstance(diagnostics, dict):
        b.problems.append('diagnostics: write {values: ..., levels: [...]}')
        diagnostics = {}
    b.unknown_keys(diagnostics, {'values', 'levels'}, 'diagnostics')
    levels = b.levels(diagnostics.get('levels') or [])
    values = b.values(diagnostics.get('values', 'all'))
    given = _given_timeouts(b, mapping.get('timeouts') or {})
    if b.problems:
        raise MappingError(listing(b.problems))
    assert primary is not None  # unset or unknown, it is one of the problems
    if diagnostics.get('values', 'all') in (None, 'all'):
        values = [ref for m in range(len(b.messages)) for ref in b.all_of(m)]
    plan = Plan(messages=b.messages, primary=primary, levels=levels, values=values,
                warnings=b.warnings, dbc_notes=loaded.notes(), dbc_info=loaded.info,
                mapped=frozenset(b.used),
                sources=b.sources, scalars=plan_parts['scalars'], enums=plan_parts['enums'],
                arrays=plan_parts['arrays'])
    _timeouts(plan, given)
    _bounds(plan)
    return plan


def _bounds(plan: Plan) -> None:
    """
    Give every signal a field reads the bounds of that field (FIELD_BOUNDS), in its DBC unit.

    The pack voltage is not bounded by the cells mapped: a mapping may read only some of the
    pack's cells (a team's test fixture maps 4 of a 400 V pack). Each message with a bounded
    signal is compiled again with them: its decoder reports a value beyond them as it does
    one outside the DBC's [min|max] (NaN, the frame malformed).
    """
    limits: dict[tuple[int, int], tuple[float, float]] = {}

    def add(key: str, ref: Ref | None, factor: float, add_: float) -> None:
        if ref is None or factor == 0:
            return
        low, high = FIELD_BOUNDS[key]
        unit = base_unit(SCALAR_UNITS.get(key) or ARRAY_UNITS[key])
        text = f'{key} {low:g}..{high:g}' + ('' if unit == '0..1' else f' {unit}')
        ends = sorted(((low - add_) / factor, (high - add_) / factor))
        where = (ref.message, ref.signal)
        old = limits.get(where)
        if old is not None:
            ends = [max(ends[0], old[0]), min(ends[1], old[1])]
            text = plan.bounds[where] + ', ' + text
        limits[where] = (ends[0], ends[1])
        plan.bounds[where] = text

    for key, scalar in plan.scalars.items():
        step: Scalar | None = scalar
        while step is not None:
            if step.ref is not None:
                add(key, step.ref, step.ref.factor, step.ref.add)
            step = step.fallback
    for key, array in plan.arrays.items():
        for ref in array.refs:
            add(key, ref, ref.factor, ref.add)
        if array.slot_message is not None and array.sample is not None:
            for signal in array.slot_signals:
                add(key, Ref(array.slot_message, signal, None, '', ''), array.factor, array.add)
    for m in sorted({m for m, _ in limits}):
        plan.messages[m] = dbc_codec.compile_message(
            plan.sources[m], {i: ends for (n, i), ends in limits.items() if n == m})


def listing(problems: list[str]) -> str:
    """One problem as it is; several as a counted list, one a line."""
    if len(problems) == 1:
        return problems[0]
    return f'{len(problems)} problems:\n  - ' + '\n  - '.join(problems)


def _given_timeouts(b: Builder, spec: Any) -> dict[int, float]:
    timeouts: dict[int, float] = {}
    if not isinstance(spec, dict):
        b.problems.append('timeouts: write {Message: seconds}')
        return timeouts
    for name, seconds in spec.items():
        m = b.message(str(name), 'timeouts')
        if not isinstance(seconds, (int, float)) or isinstance(seconds, bool) \
                or not 0.01 <= seconds <= 3600:
            b.problems.append(f'timeouts.{name}: {seconds!r} is not 0.01..3600 s')
        elif m is not None:
            timeouts[m] = float(seconds)
    return timeouts


def given_timeouts(plan: Plan, items: Iterable[str]) -> None:
    """
    Apply the ``timeouts`` parameter ('Message=seconds' each) over the plan's timeouts.

    ConfigError names every entry that is not a mapped message with 0.01..3600 s.
    """
    names = {m.name: n for n, m in enumerate(plan.messages)}
    problems = []
    for item in items:
        name, sep, text = str(item).partition('=')
        name = name.strip()
        try:
            seconds = float(text) if sep else math.nan
        except ValueError:
            seconds = math.nan
        if name not in names:
            problems.append(f'timeouts: {item!r}: {name!r} is not a message the mapping reads'
                            + dbc_codec.closest(name, list(names)))
        elif not 0.01 <= seconds <= 3600:
            problems.append(f"timeouts: {item!r}: write 'Message=seconds' (0.01..3600 s)")
        else:
            plan.timeouts[names[name]] = seconds
            plan.timeout_origin[names[name]] = 'the timeouts parameter'
    if problems:
        raise ConfigError(listing(problems))


def _timeouts(plan: Plan, given: dict[int, float]) -> None:
    """
    Give each message its own timeout: the mapping's, else from the DBC's period.

    A few periods (TIMEOUT_PERIODS) of the whole rotation: a multiplexed message sends one
    multiplexer value a frame, a positioned array one position; at least MIN_TIMEOUT. A
    message the DBC gives no period (and the primary, whose silence is the device's
    stale_timeout) keeps stale_timeout.
    """
    for m, compiled in enumerate(plan.messages):
        if m in given:
            plan.timeouts[m] = given[m]
            plan.timeout_origin[m] = "the mapping's timeouts"
            continue
        period, source = cycle_time(plan.sources[m])
        if m == plan.primary or period is None:
            plan.timeout_origin[m] = 'stale_timeout' + (
                ' (the primary)' if m == plan.primary else ' (the DBC gives no period)')
            continue
        rotation, what = 1, ''
        muxes = {v for s in compiled.signals for v in (s.mux_ids or ())}
        if compiled.mux_index is not None and len(muxes) > 1:
            rotation, what = len(muxes), f' x {len(muxes)} multiplexer values'
        for array in plan.arrays.values():
            if array.slot_message == m and array.slot_signals:
                positions = -(-array.count // len(array.slot_signals))
                if positions > rotation:
                    rotation, what = positions, f' x {positions} positions'
        plan.timeouts[m] = max(MIN_TIMEOUT, TIMEOUT_PERIODS * period * rotation)
        plan.timeout_origin[m] = f'{TIMEOUT_PERIODS} x {source}{what}'


def resolve_files(dbc_file: str | None, mapping_file: str | None,
                  profile: str | None = None) -> tuple[str | None, str | None, list[str]]:
    """Return the DBC and mapping a configuration means (a profile's), and its problems."""
    if not profile:
        return dbc_file, mapping_file, []
    if dbc_file:
        return None, None, [f'profile {profile} brings its own DBC: remove dbc_file (or the '
                            'profile); mapping_file may replace the profile\'s mapping']
    try:
        dbc, mapping = profile_files(profile)
    except ConfigError as exc:
        return None, None, [str(exc)]
    return str(dbc), mapping_file or str(mapping), []


def load_plan(dbc_file: str | None, mapping_file: str | None,
              profile: str | None = None) -> Plan:
    """Find, load and check both files; MappingError names every problem (missing too)."""
    dbc_file, mapping_file, problems = resolve_files(dbc_file, mapping_file, profile)
    if problems:  # the profile: its own words
        raise MappingError(listing(problems))
    loaded = mapping = None
    dbc_path = _find('dbc_file', dbc_file, 'the path of your DBC (or a profile: '
                     'foxbms2, orion_bms2)', problems)
    if dbc_path is not None:
        try:
            loaded = read_dbc(dbc_path)
        except OSError as exc:
            problems.append(f'dbc_file {str(dbc_path)!r} cannot be read: {exc.strerror}')
        except DbcLoadError as exc:
            problems.append(f'dbc_file {str(dbc_path)!r} does not load: {exc}')
        except Exception as exc:  # cantools on a file it trips over: a reason, no trace
            problems.append(f'dbc_file {str(dbc_path)!r} does not load: cantools: '
                            f'{type(exc).__name__}: {exc}')
    mapping_path = _find('mapping_file', mapping_file, 'the path of your mapping YAML',
                         problems)
    if mapping_path is not None:
        try:
            mapping = load_yaml(mapping_path.read_text(encoding='utf-8'),
                                f'mapping_file {str(mapping_path)!r}')
        except ConfigError as exc:  # an alias bomb
            problems.append(str(exc))
        except OSError as exc:
            problems.append(f'mapping_file {str(mapping_path)!r} cannot be read: '
                            f'{exc.strerror}')
        except yaml.YAMLError as exc:
            problems.append(yaml_problem(str(mapping_path), exc))
    if problems:
        raise MappingError(listing(problems))
    assert loaded is not None
    plan = build_plan(loaded, mapping)
    plan.files = (str(dbc_path), str(mapping_path))
    return plan


def _find(key: str, given: str | None, what: str, problems: list[str]) -> Path | None:
    """Locate one of the two files; a problem (unset, not found) otherwise."""
    if not given:
        problems.append(f'{key} is not set: give {what}')
        return None
    path, looked = locate(given)
    if path is None:
        problems.append(not_found(key, given, looked))
        return None
    problem = file_problem(path)
    if problem:  # found, but a directory, a FIFO, /dev/zero: reading it fails or never ends
        problems.append(f'{key} {str(path)!r} {problem}')
        return None
    return path


def not_found(key: str, given: str, looked: list) -> str:
    """Say that a file is missing and every place it was looked for."""
    return (f'{key} {given!r} not found; looked in: ' + ', '.join(str(p) for p in looked)
            + ' (a relative path: the working directory, the params file\'s folder, the '
            'package share folder)')


def yaml_problem(path: str, exc: yaml.YAMLError) -> str:
    """Say a YAML error as YAML does, with the file, line and column (several lines)."""
    mark = getattr(exc, 'problem_mark', None)
    problem = getattr(exc, 'problem', None) or str(exc)
    context = getattr(exc, 'context', None)
    where = f'{path}, line {mark.line + 1}, column {mark.column + 1}' if mark else path
    text = f'mapping_file {where}: not valid YAML: {problem}' + (
        f' ({context})' if context else '')
    snippet = mark.get_snippet() if mark is not None else None
    if snippet:
        text += '\n' + '\n'.join('    ' + line for line in snippet.splitlines())
    return text
