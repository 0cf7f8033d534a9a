# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The cell arrays of a dbc mapping: templates, lists, positioned arrays, validity flags.

A validity flag is read as the DBC means it: a flag whose value table names its values
``Valid`` / ``Invalid`` (any case) is read by those names, whatever the signal is called
(foxBMS 2 names its flags ``CellVoltage_000_invalidFlag`` and sends 1 "Valid"). Without
such a table, ``invalid:`` means "any value but 0 is invalid" and ``valid:`` "0 is
invalid"; ``{signal: ..., when: V}`` says the value explicitly, and a ``when`` that
contradicts the table stops the bridge. doc/own_bms.md documents the keys.
"""
from __future__ import annotations

from typing import Any

from ams_can_bridge.protocols.dbc_mapping.builder import Builder
from ams_can_bridge.protocols.dbc_mapping.plan import Array, ARRAY_UNITS, FlagRule, Ref
from ams_can_bridge.protocols import dbc_codec

ARRAY_KEYS = {'signal', 'signals', 'count', 'first', 'invalid', 'valid', 'per_frame',
              'position', 'scale', 'offset', 'unit'}
MAX_COUNT = 1024


def build_array(b: Builder, key: str, spec: Any, where: str) -> Array | None:
    """Check one cell array of battery_state; None (and problems in b) when unusable."""
    wanted = ARRAY_UNITS[key]
    if isinstance(spec, list):
        spec = {'signals': spec}
    if not isinstance(spec, dict):
        b.problems.append(f'{where}: write {{signal: "Msg.sig_{{i}}", count: N}} or a '
                          'list of "Message.signal"')
        return None
    b.unknown_keys(spec, ARRAY_KEYS, where)
    if 'position' in spec:
        return _slot_array(b, spec, where, wanted)
    flag_key = 'valid' if 'valid' in spec else 'invalid'
    if 'valid' in spec and 'invalid' in spec:
        b.problems.append(f'{where}: give invalid: or valid:, not both')
        return None
    flag_spec = spec.get(flag_key)
    flag_template, when = (flag_spec.get('signal'), flag_spec.get('when')) \
        if isinstance(flag_spec, dict) else (flag_spec, None)
    if isinstance(flag_spec, dict):
        b.unknown_keys(flag_spec, {'signal', 'when'}, f'{where}.{flag_key}')
    if 'signals' in spec:
        names: list[Any] | None = list(spec['signals'] or [])
        source = 'the list ' + ', '.join(str(n) for n in (names or []))
        flag_names: list[Any] | None = (list(flag_template) if isinstance(flag_template, list)
                                        else [None] * len(names or []))
        if flag_template is not None and len(flag_names or []) != len(names or []):
            b.problems.append(f'{where}.{flag_key}: with a list of signals, give a list of '
                              'as many flag signals')
            return None
    else:
        count, first = spec.get('count'), spec.get('first', 0)
        if not isinstance(count, int) or isinstance(count, bool) \
                or not 1 <= count <= MAX_COUNT:
            b.problems.append(f'{where}.count: {count!r}: give the number of elements '
                              f'(1..{MAX_COUNT})')
            return None
        names = _expand(b, spec.get('signal'), count, first, where)
        source = f'{spec.get("signal")}, i = {first}..{first + count - 1}'
        flag_names = (_expand(b, flag_template, count, first, f'{where}.{flag_key}')
                      if flag_template else [None] * count)
    if names is None or flag_names is None:
        return None
    refs, flags = [], []
    before = len(b.problems)
    for name, flag in zip(names, flag_names):
        ref = b.ref(name, where, wanted, spec.get('scale'), spec.get('offset'),
                    spec.get('unit'))
        if ref is not None:
            refs.append(ref)
        flags.append(b.ref(flag, f'{where}.{flag_key}') if flag else None)
        if len(b.problems) - before >= 3:
            b.problems.append(f'{where}: (further elements not checked)')
            return None
    if len(b.problems) > before:
        return None
    rule = None
    if flag_template is not None:
        rule = _flag_rule(b, [f for f in flags if f is not None], flag_key, when,
                          f'{where}.{flag_key}')
        if rule is None:
            return None
    return Array(count=len(refs), refs=tuple(refs), invalid=tuple(flags), flag_rule=rule,
                 sample=refs[0] if refs else None,
                 source=source, flag_source=str(flag_template or ''))


def _flag_rule(b: Builder, flags: list[Ref], key: str, when: Any,
               where: str) -> FlagRule | None:
    """Say what the flags' values mean: from their value table, else from the mapping."""
    rules = set()
    for flag in flags:
        rules.add(_table_rule(b.messages[flag.message].signals[flag.signal]))
    if len(rules) > 1:
        b.problems.append(f'{where}: the flag signals do not share one value table '
                          '(Valid / Invalid): map them as separate arrays or fix the DBC')
        return None
    table = rules.pop() if rules else None
    info = b.messages[flags[0].message].signals[flags[0].signal] if flags else None
    value = None
    if when is not None and info is not None:
        value = b.signal_value(info, when, f'{where}.when')
        if value is None:
            return None
    if table is not None:
        if value is not None and table.invalid(value) != (key == 'invalid'):
            meaning = 'invalid' if key == 'invalid' else 'valid'
            b.problems.append(
                f'{where}: when {when!r} calls {value:g} {meaning}, but the DBC\'s value table '
                f'of {info.name if info else "the flag"} says it is not ({table.why}): '
                'remove when (the table decides) or fix the DBC')
            return None
        return table
    if value is not None:
        return FlagRule(frozenset({value}), key == 'invalid',
                        f'the mapping: {key}: {{when: {when}}}')
    if key == 'invalid':
        return FlagRule(frozenset({0.0}), False, 'no Valid/Invalid value table in the DBC: '
                        'any value but 0 means invalid')
    return FlagRule(frozenset({0.0}), True, 'no Valid/Invalid value table in the DBC: 0 '
                    'means invalid')


def _table_rule(info: dbc_codec.SignalInfo) -> FlagRule | None:
    """Read a flag's value table: the values it names Invalid (or, alone, Valid)."""
    named = {raw: text.strip().lower() for raw, text in info.choices.items()}
    invalid = frozenset(info.physical(raw) for raw, text in named.items() if text == 'invalid')
    valid = frozenset(info.physical(raw) for raw, text in named.items() if text == 'valid')
    if invalid:
        listed = ', '.join(f'{v:g} "{info.choices[raw]}"' for raw in sorted(info.choices)
                           if (v := info.physical(raw)) in invalid)
        return FlagRule(invalid, True, f'the DBC value table names {listed}')
    if valid:
        listed = ', '.join(f'{v:g} "{info.choices[raw]}"' for raw in sorted(info.choices)
                           if (v := info.physical(raw)) in valid)
        return FlagRule(valid, False, f'the DBC value table names {listed}')
    return None


def _expand(b: Builder, template: Any, count: int, first: Any,
            where: str) -> list[str] | None:
    if not isinstance(template, str) or not isinstance(first, int):
        b.problems.append(f'{where}: signal must be a "Message.signal_{{i}}" template '
                          'and first an integer')
        return None
    try:
        names = [template.format(i=first + n) for n in range(count)]
    except (KeyError, IndexError, ValueError) as exc:
        b.problems.append(f'{where}: template {template!r} does not resolve with {{i}}:'
                          f' {exc!r}')
        return None
    if count > 1 and len(set(names)) == 1:
        b.problems.append(f'{where}: template {template!r} has no {{i}}')
        return None
    return names


def _slot_array(b: Builder, spec: dict, where: str, wanted: str) -> Array | None:
    per_frame, count = spec.get('per_frame'), spec.get('count')
    position = spec.get('position')
    if not isinstance(per_frame, int) or not isinstance(count, int) \
            or not isinstance(position, dict) or not 1 <= count <= MAX_COUNT:
        b.problems.append(f'{where}: a positioned array needs per_frame (elements per '
                          f'frame), count (1..{MAX_COUNT}) and position {{selector signal: '
                          '{stride: N, first: F}}')
        return None
    names = _expand(b, spec.get('signal'), per_frame, spec.get('first', 0), where)
    if names is None:
        return None
    found = [b.ref(n, where, wanted, spec.get('scale'), spec.get('offset'), spec.get('unit'))
             for n in names]
    refs = [r for r in found if r is not None]
    if len(refs) != len(found):
        return None
    message = refs[0].message
    if any(r.message != message for r in refs):
        b.problems.append(f'{where}: a positioned array takes its elements from one message')
        return None
    selectors = []
    compiled = b.messages[message]
    for name, how in position.items():
        how = how if isinstance(how, dict) else {'stride': how}
        i = compiled.index.get(str(name))
        stride, first = how.get('stride'), how.get('first', 0)
        if i is None:
            b.problems.append(f'{where}.position: {name!r} is not a signal of {compiled.name}'
                              + dbc_codec.closest(str(name), list(compiled.index)))
        elif not isinstance(stride, int) or not isinstance(first, (int, float)):
            b.problems.append(f'{where}.position.{name}: stride must be an integer')
        else:
            b.used.add((message, i))
            selectors.append((i, float(first), stride))
    if len(selectors) != len(position):
        return None
    return Array(count=count, sample=refs[0], slot_message=message,
                 slot_signals=tuple(r.signal for r in refs), selectors=tuple(selectors),
                 factor=refs[0].factor, add=refs[0].add,
                 source=f'{spec.get("signal")} positioned by '
                 + ', '.join(str(n) for n in position))
