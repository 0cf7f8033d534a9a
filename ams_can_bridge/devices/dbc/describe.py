# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The start log of a dbc device: what each mapped field is computed from, in words.

One line per mapped field (``percentage [0..1] = MSGID_0X6B0.Pack_SOC [Percent] x 0.01``),
per array with its validity rule, per level rule with its threshold's unit (the signal's
DBC unit: thresholds are compared with the DBC value, not the converted one) and per
message its timeout and where it comes from.
"""
from __future__ import annotations

from ams_can_bridge.protocols.dbc_mapping.plan import (
    ARRAY_UNITS, base_unit, CONDITION_TEXT, Enum, ENUMS, LEARNED_PERIODS, Plan, Ref, Scalar,
    SCALAR_UNITS)


def formula(ref: Ref, named: bool = True) -> str:
    """Return 'Msg.sig [unit] x 0.001 x -1 (scale) + 2 (offset)' for a converted signal."""
    text = (f'{ref.name} ' if named else '') + f'[{ref.unit or "no unit"}]'
    if ref.converted:
        factor = ref.factor / ref.scale
        add = (ref.add - ref.offset) / ref.scale
        if factor != 1.0:
            text += f' x {factor:g}'
        if add:
            text += f' {"-" if add < 0 else "+"} {abs(add):g}'
    if ref.scale != 1.0:
        text += f' x {ref.scale:g} (scale)'
    if ref.offset:
        text += f' {"-" if ref.offset < 0 else "+"} {abs(ref.offset):g} (offset)'
    return text


def _scalar(scalar: Scalar) -> str:
    if scalar.constant is not None:
        return f'{scalar.constant:g} (a constant)'
    if scalar.ref is not None:
        return formula(scalar.ref)
    text = f'{scalar.reduce} of the known {scalar.of}'
    if scalar.reduce == 'sum':
        text = f'sum of {scalar.of} (unknown while any element is)'
    if scalar.fallback is not None:
        text += f', else {_scalar(scalar.fallback)}'
    return text


def _enum(plan: Plan, key: str, spec: Enum) -> str:
    enum_cls = ENUMS[key]
    if spec.constant is not None:
        return f'{key} = {enum_cls(spec.constant).name} (a constant)'
    parts = []
    for rule in spec.rules:
        info = plan.messages[rule.ref.message].signals[rule.ref.signal]
        names = [f'{info.choices.get(int(v), f"{v:g}") if v == int(v) else f"{v:g}"} -> '
                 f'{enum_cls(t).name}' for v, t in rule.table.items()]
        if rule.otherwise is not None:
            names.append(f'otherwise {enum_cls(rule.otherwise).name}')
        parts.append(f'{rule.ref.name}: {", ".join(names)}')
    tail = ' (else from the current\'s sign)' if key == 'power_supply_status' else ''
    return f'{key} = ' + '; then '.join(parts) + tail


def start_lines(plan: Plan, stale_timeout: float) -> list[str]:
    """Return the start log's lines of one device (INFO), in mapping order."""
    lines = [f'DBC {plan.files[0]}, mapping {plan.files[1]}']
    for key, scalar in plan.scalars.items():
        lines.append(f'{key} [{base_unit(SCALAR_UNITS[key])}] = {_scalar(scalar)}')
    for key, array in plan.arrays.items():
        unit = base_unit(ARRAY_UNITS[key])
        sample = '' if array.sample is None else f' (each {formula(array.sample, False)})'
        line = f'{key} [{unit}] x {array.count} = {array.source}{sample}'
        if array.flag_rule is not None:
            line += '; ' + array.flag_rule.text(array.flag_source)
        lines.append(line)
    for key, spec in plan.enums.items():
        lines.append(_enum(plan, key, spec))
    for n, rule in enumerate(plan.levels):
        info = plan.messages[rule.ref.message].signals[rule.ref.signal]
        if rule.condition.endswith('_bits'):
            threshold = f'0x{int(rule.threshold):X}'
        else:
            name = info.choices.get(int(rule.threshold)) \
                if rule.threshold == int(rule.threshold) else None
            threshold = f'{rule.threshold:g}' + (f' "{name}"' if name else '') + (
                f' {info.unit}' if info.unit else '')
        lines.append(f'levels[{n}]: {rule.level.name} when {rule.ref.name} '
                     f'{CONDITION_TEXT[rule.condition]} {threshold} (the DBC value, in its '
                     'own unit)')
    for m, compiled in enumerate(plan.messages):
        seconds = plan.timeouts.get(m, stale_timeout)
        lines.append(f'timeout {compiled.name} (0x{compiled.frame_id:X}): {seconds:g} s, '
                     f'{plan.timeout_origin.get(m, "stale_timeout")}')
    lines.append(f'timeouts grow to {LEARNED_PERIODS} x the period each message is heard at '
                 '(learned from the traffic); the timeouts parameter sets one from the start')
    if plan.bounds:
        lines.append('refused as implausible (never published, the frame malformed): '
                     + '; '.join(f'{plan.messages[m].name}.{plan.messages[m].signals[i].name} '
                                 f'beyond {text}' for (m, i), text in plan.bounds.items()))
    return lines
