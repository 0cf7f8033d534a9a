# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What a dbc device's diagnostics say beyond its level rules: missing data, and a size cap.

Missing data is never OK: a mapped field or array element that is unknown because its
message (or multiplexer group, or array element) has not arrived within its timeout since
start, or has expired, makes the device WARN with a message that counts and names what is
missing (``12 of 16 cell voltages unknown: f_CellVoltages mux 1..3 not received``); an
element the BMS flags invalid, or a value outside its DBC range (or implausible for its
field: the device names those), is named too. A multiplexer value or position never heard
is missing as soon as every other group of its message came twice. The
BatteryState stays honest (NaN) as before.

A status carries at most VALUES_CAP signal values besides the mapped ones (the signals a
field or level reads always stay, as do the level message and the counters): ``values: all``
on a DBC of hundreds of signals would otherwise put all of them in every /diagnostics
message.
"""
from __future__ import annotations

from typing import Any, Callable, Iterable

from ams_can_bridge.protocols.dbc_mapping.plan import Array, ARRAY_LABELS, Plan, Ref
from ams_can_bridge.devices.timed import NEVER

VALUES_CAP = 100  # signal values a status carries besides the mapped ones
WARNINGS_CAP = 30  # warnings listed one by one (in the log and as values)

# why an element is unknown (the order the message lists them in)
NOT_RECEIVED, EXPIRED, INVALID, OUT_OF_RANGE, WAITING = (
    'not received', 'expired', 'flagged invalid', 'outside its DBC range or implausible',
    'waiting')


def ranges(numbers: Iterable[int]) -> str:
    """'1..3, 5' for 1, 2, 3, 5."""
    runs: list[list[int]] = []
    for n in sorted(set(numbers)):
        if runs and n == runs[-1][1] + 1:
            runs[-1][1] = n
        else:
            runs.append([n, n])
    return ', '.join(str(a) if a == b else f'{a}..{b}' for a, b in runs)


class Missing:
    """Why values are unknown, collected per message and multiplexer value (or position)."""

    def __init__(self, plan: Plan) -> None:
        self.plan = plan
        self.groups: dict[tuple[int, str], set[int]] = {}  # (message, why) -> mux values
        self.whole: dict[int, str] = {}  # message (not multiplexed) -> why
        self.flagged = 0
        self.out_of_range = 0

    def add(self, message: int, mux: int | None, why: str) -> None:
        if why == INVALID:
            self.flagged += 1
        elif why == OUT_OF_RANGE:
            self.out_of_range += 1
        elif mux is None:
            self.whole[message] = why
        else:
            self.groups.setdefault((message, why), set()).add(mux)

    def text(self, label: str = 'mux') -> str:
        parts = [f'{self.plan.messages[m].name} {why}' for m, why in self.whole.items()]
        for m in dict.fromkeys(m for m, _ in self.groups):
            parts.append(self.plan.messages[m].name + ' ' + ', '.join(
                f'{label} {ranges(self.groups[(m, why)])} {why}'
                for why in (NOT_RECEIVED, EXPIRED) if (m, why) in self.groups))
        if self.flagged:
            parts.append(f'{self.flagged} {INVALID} by the BMS')
        if self.out_of_range:
            parts.append(f'{self.out_of_range} {OUT_OF_RANGE}')
        return ', '.join(parts)


def missing_report(device: Any, arrays: dict[str, list[float]],
                   scalars: dict[str, float], now: float) -> list[str]:
    """
    Return one line per mapped field with unknown data not explained by the start-up wait.

    ``device`` is the DbcDevice (lock held): its plan, groups, slots and timeouts.
    """
    plan: Plan = device.plan
    lines, incomplete = [], set()
    for key, values in arrays.items():
        array = plan.arrays[key]
        why = Missing(plan)
        unknown = sum(_element_reason(device, array, key, n, now, why) != WAITING
                      for n, value in enumerate(values) if value != value)
        if unknown:
            incomplete.add(key)
            label = 'element' if array.slot_message is not None else 'mux'
            lines.append(f'{unknown} of {array.count} {ARRAY_LABELS[key]} unknown: '
                         f'{why.text(label)}')
    for key, value in scalars.items():
        scalar = plan.scalars[key]
        if value == value or scalar.constant is not None:
            continue
        why = Missing(plan)
        if scalar.ref is not None and _reason(device, scalar.ref, now, why) != WAITING:
            lines.append(f'{key} unknown: {why.text()}')
        elif scalar.reduce and scalar.of in incomplete:
            lines.append(f'{key} unknown: {scalar.reduce} of {ARRAY_LABELS[scalar.of]}, '
                         'some unknown')
    for key, spec in plan.enums.items():
        why = Missing(plan)
        reasons = [_reason(device, rule.ref, now, why) for rule in spec.rules]
        if reasons and all(r in (NOT_RECEIVED, EXPIRED) for r in reasons):
            lines.append(f'{key} unknown: {why.text()}')
    return lines


def _key(device: Any, ref: Ref) -> tuple[int, Any]:
    """Return the group a signal's value comes from (of a multiplexed one: the newest)."""
    if ref.mux is None:
        return ref.message, None
    return max(((ref.message, mux) for mux in ref.mux), key=device.groups.seen)


def _state(device: Any, key: tuple[int, Any], seen: float, now: float) -> str:
    """Return 'fresh', WAITING, NOT_RECEIVED or EXPIRED for one group (or position)."""
    timeout = device.group_timeout(key[0])
    if seen == NEVER:
        # missing once its message's other groups each came twice without it
        if key[1] is not None and device.all_arrived_twice(key[0]):
            return NOT_RECEIVED
        return WAITING if now - device.started <= timeout else NOT_RECEIVED
    return 'fresh' if now - seen <= timeout else EXPIRED


def _reason(device: Any, ref: Ref, now: float, why: Missing,
            flag: Ref | None = None, rule: Any = None) -> str:
    """Find why one signal's value is unknown; record it in why; return the reason."""
    key = _key(device, ref)
    state = _state(device, key, device.groups.seen(key), now)
    if state == 'fresh':
        invalid = flag is not None and rule is not None and rule.invalid(device.raw(flag, now))
        state = INVALID if invalid else OUT_OF_RANGE
    if state != WAITING:
        why.add(ref.message, key[1], state)
    return state


def _element_reason(device: Any, array: Array, key: str, n: int, now: float,
                    why: Missing) -> str:
    if array.slot_message is None:
        flag = array.invalid[n] if array.invalid else None
        return _reason(device, array.refs[n], now, why, flag, array.flag_rule)
    state = _state(device, (array.slot_message, n), device.slot_elements(key).seen[n], now)
    if state == 'fresh':
        state = OUT_OF_RANGE
    if state != WAITING:
        why.add(array.slot_message, n, state)
    return state


def capped_values(plan: Plan, read: Callable[[Ref], str]) -> dict[str, str]:
    """Return the signal values of a status: every mapped one, others up to VALUES_CAP."""
    values: dict[str, str] = {}
    others = left = 0
    for ref in plan.values:
        mapped = (ref.message, ref.signal) in plan.mapped
        if not mapped and others >= VALUES_CAP:
            left += 1
            continue
        others += not mapped
        values[ref.name + (f' [{ref.unit}]' if ref.unit else '')] = read(ref)
    if left:
        values['values not shown'] = (
            f'{left} more signals (a status carries at most {VALUES_CAP} besides the mapped '
            'ones: list the ones you need in diagnostics.values)')
    return values


def listed(label: str, items: list[str]) -> dict[str, str]:
    """Return '<label> 1'.. values, at most WARNINGS_CAP, and how many more there are."""
    out = {f'{label} {n + 1}': text for n, text in enumerate(items[:WARNINGS_CAP])}
    if len(items) > WARNINGS_CAP:
        out[f'{label}s not shown'] = str(len(items) - WARNINGS_CAP)
    return out
