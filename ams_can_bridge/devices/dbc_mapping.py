"""
The mapping of a ``dbc`` device: a team's DBC signals -> BatteryState fields and diagnostics.

README "Your own BMS" documents the file; docs/protocols.md section 8 the decisions. Loading
checks everything at once and raises ``MappingError`` listing every problem (the bridge
stops with exit 2): each referenced message and signal must exist (the error names the
closest names), the primary must be set, array templates must resolve, map keys must be
value names (VAL_) or numbers. Units come from the DBC and are converted to what
BatteryState wants (mV -> V, % -> 0..1, K -> degC, ...); a unit we do not know without a
``scale`` is a warning naming the signal (the value is taken as it is).

This module reads the two files and walks the mapping's structure; the checks of each entry
(references, fields, levels) are ``devices.dbc_builder``'s.
"""
from __future__ import annotations

from typing import Any

import yaml

from ams_can_bridge.devices.dbc_builder import Builder
from ams_can_bridge.devices.dbc_plan import (
    Array, ARRAY_UNITS, Enum, ENUMS, MappingError, Plan, resolve_path, Scalar, SCALAR_UNITS,
    TOP_LEVEL)
from ams_can_bridge.protocols import dbc_codec


def build_plan(db: Any, mapping: Any) -> Plan:
    """Check a loaded mapping against a loaded DBC; MappingError lists every problem."""
    if not isinstance(mapping, dict):
        raise MappingError('the mapping file is not a YAML mapping (primary:, battery_state:)')
    b = Builder(db, mapping)
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
            result, part = b.array(key, spec, where), 'arrays'
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
    timeouts = {}
    spec = mapping.get('timeouts') or {}
    if not isinstance(spec, dict):
        b.problems.append('timeouts: write {Message: seconds}')
        spec = {}
    for name, seconds in spec.items():
        m = b.message(str(name), 'timeouts')
        if not isinstance(seconds, (int, float)) or isinstance(seconds, bool) \
                or not 0.01 <= seconds <= 3600:
            b.problems.append(f'timeouts.{name}: {seconds!r} is not 0.01..3600 s')
        elif m is not None:
            timeouts[m] = float(seconds)
    if b.problems:
        raise MappingError('\n'.join(b.problems))
    assert primary is not None  # unset or unknown, it is one of the problems
    if diagnostics.get('values', 'all') in (None, 'all'):
        values = [ref for m in range(len(b.messages)) for ref in b.all_of(m)]
    return Plan(messages=b.messages, primary=primary, levels=levels, values=values,
                warnings=b.warnings, timeouts=timeouts, **plan_parts)


def load_plan(dbc_file: str | None, mapping_file: str | None) -> Plan:
    """Load and check both files; MappingError names every problem (missing files too)."""
    problems = []
    db = mapping = None
    if not dbc_file:
        problems.append('dbc_file is not set: give the path of your DBC')
    else:
        path = resolve_path(dbc_file)
        try:
            db = dbc_codec.load(str(path))
        except FileNotFoundError:
            problems.append(f'dbc_file {str(path)!r} not found (a relative path is taken from '
                            'the working directory, then from the package share folder)')
        except Exception as exc:  # cantools' parse and strict-layout errors
            problems.append(f'dbc_file {str(path)!r} does not load (cantools, strict): {exc}')
    if not mapping_file:
        problems.append('mapping_file is not set: give the path of your mapping YAML')
    else:
        path = resolve_path(mapping_file)
        try:
            mapping = yaml.safe_load(path.read_text(encoding='utf-8'))
        except OSError as exc:
            problems.append(f'mapping_file {str(path)!r} cannot be read: {exc.strerror}')
        except yaml.YAMLError as exc:
            problems.append(f'mapping_file {str(path)!r} is not valid YAML: {exc}')
    if problems:
        raise MappingError('\n'.join(problems))
    return build_plan(db, mapping)
