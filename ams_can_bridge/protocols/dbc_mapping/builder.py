# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The checks of each entry of a dbc mapping, collecting every problem instead of stopping.

``devices.dbc.mapping`` walks the file (its top-level keys, primary, timeouts) and hands each
entry to a ``Builder``: a "Message.signal" reference (the closest names when it is not in the
DBC; a broken message or a duplicated name refused; the unit converted to what the field
wants), a BatteryState scalar or enum, a diagnostics level or value list. Arrays are
``devices.dbc.arrays``'. doc/protocols.md section 8 holds the rules.
"""
from __future__ import annotations

import re
from typing import Any

from ams_can_bridge.protocols.dbc_mapping.plan import (
    base_unit, CONDITIONS, Enum, EnumRule, ENUMS, LevelRule, LEVELS, REDUCERS, Ref, Scalar,
    SCALAR_UNITS)
from ams_can_bridge.protocols.dbc_mapping.units import lookup, QUANTITY_NAMES, unit_text
from ams_can_bridge.protocols import dbc_codec
from ams_can_bridge.protocols.dbc_load import DUPLICATE_MARK, LoadedDbc

# a plausible value of each quantity, to show what a wrong scale would make of it
_SAMPLE = {'V': 3.7, 'A': 20.0, 'Ah': 20.0, 'fraction': 0.75, 'degC': 25.0}


def natural_key(text: str) -> tuple:
    """Sort 'Cell_2' before 'Cell_10' (numbers as numbers)."""
    return tuple(int(part) if part.isdigit() else part.lower()
                 for part in re.split(r'(\d+)', text))


def _within_fraction(info: dbc_codec.SignalInfo) -> bool:
    """Tell whether a signal's DBC range says it is a ratio 0..1 already."""
    return (info.minimum is not None and info.maximum is not None
            and info.minimum >= 0 and info.maximum <= 1)


def _fraction_problem(where: str, name: str, spelled: str,
                      info: dbc_codec.SignalInfo) -> str:
    """Say that a ratio's unit must be given: a percentage published as 805 is no ratio."""
    top = info.maximum
    guess = {100.0: "'%'", 1000.0: "'‰' (0.1 % per bit)", 10000.0: "'0.01%'"}.get(
        float(top) if top is not None else -1.0)
    span = (f'its DBC range {info.minimum:g}..{top:g}' if top is not None
            and info.minimum is not None else 'the DBC gives it no range')
    return (f'{where}: {name} has unit {spelled!r}, which is not a ratio unit we know, and '
            f'{span} is not 0..1: give its unit with unit: ('
            + (f'{guess} reads that range as 0..100 %; ' if guess else '')
            + "'%', '‰', '0.1%', '0.01%' or '0..1'; doc/own_bms.md: units)")


class Builder:
    """Walks the mapping, collecting every problem instead of stopping at the first."""

    def __init__(self, loaded: LoadedDbc, mapping: dict) -> None:
        self.loaded = loaded
        self.db = loaded.db
        self.mapping = mapping
        self.problems: list[str] = []
        self.warnings: list[str] = []
        self.messages: list[dbc_codec.CompiledMessage] = []
        self.sources: list[Any] = []  # the cantools message of each compiled one
        self.used: set[tuple[int, int]] = set()  # (message, signal) a field or level reads
        self._by_name: dict[str, int] = {}

    def message(self, name: str, where: str) -> int | None:
        if name in self._by_name:
            return self._by_name[name]
        broken = self.loaded.broken.get(name)
        if broken is not None:
            self.problems.append(f'{where}: message {name} is broken in the DBC ({broken}): '
                                 'fix it in the DBC or map another message')
            return None
        try:
            msg = self.db.get_message_by_name(name)
        except KeyError:
            self.problems.append(f'{where}: message {name!r} is not in the DBC'
                                 + dbc_codec.closest(name, [m.name for m in self.db.messages]))
            return None
        self._by_name[name] = len(self.messages)
        self.messages.append(dbc_codec.compile_message(msg))
        self.sources.append(msg)
        return self._by_name[name]

    def ref(self, text: Any, where: str, wanted: str | None = None, scale: Any = None,
            offset: Any = None, unit: Any = None, used: bool = True) -> Ref | None:
        """Check a "Message.signal" and its conversion to the wanted quantity (V, A, ...)."""
        if not isinstance(text, str) or text.count('.') != 1:
            self.problems.append(f'{where}: {text!r} is not "Message.signal"')
            return None
        msg_name, sig_name = text.split('.')
        m = self.message(msg_name, where)
        if m is None:
            return None
        compiled = self.messages[m]
        count = self.loaded.duplicates.get(msg_name, {}).get(sig_name)
        if count:
            self.problems.append(
                f'{where}: signal {sig_name} appears {count} times in message {msg_name} of '
                'the DBC, so it cannot be told apart: give each its own name in the DBC')
            return None
        i = None if DUPLICATE_MARK in sig_name else compiled.index.get(sig_name)
        if i is None:
            self.problems.append(f'{where}: signal {sig_name!r} is not in message {msg_name}'
                                 + dbc_codec.closest(sig_name, [
                                     n for n in compiled.index if DUPLICATE_MARK not in n]))
            return None
        info = compiled.signals[i]
        conversion = self._conversion(info, text, where, wanted, scale, offset, unit)
        if conversion is None:
            return None
        unit_used, factor, add, converted, scale_f, offset_f = conversion
        if used:
            self.used.add((m, i))
        # nested multiplexing (decoded by cantools): one merged group per message
        mux = info.mux_ids if compiled.mux_index is not None else None
        return Ref(m, i, mux, text, unit_used, factor * scale_f, add * scale_f + offset_f,
                   converted, scale_f, offset_f)

    def _conversion(self, info: dbc_codec.SignalInfo, name: str, where: str,
                    wanted: str | None, scale: Any, offset: Any, unit: Any
                    ) -> tuple[str, float, float, str, float, float] | None:
        """
        Return (unit, factor, add, converted unit, scale, offset), or None (a problem).

        The rule that makes the common mistake loud: the device converts a known unit
        itself, so a mapping's scale on such a signal may only flip the sign.
        """
        for label, value in (('scale', scale), ('offset', offset)):
            if value is not None and (isinstance(value, bool)
                                      or not isinstance(value, (int, float))):
                self.problems.append(f'{where}: {label} {value!r} is not a number')
                return None
        scale_f = 1.0 if scale is None else float(scale)
        offset_f = 0.0 if offset is None else float(offset)
        dbc_unit = unit_text(info.unit)
        if wanted is None:
            return dbc_unit, 1.0, 0.0, '', 1.0, 0.0
        spelled = dbc_unit if unit is None else str(unit)
        known = lookup(spelled)
        target = QUANTITY_NAMES[wanted]
        if unit is not None and (known is None or known.quantity != wanted):
            self.problems.append(f'{where}: unit {unit!r} is not {target} unit this package '
                                 'knows (doc/own_bms.md: units)')
            return None
        if known is None:
            if wanted == 'fraction' and scale is None and offset is None \
                    and not _within_fraction(info):
                self.problems.append(_fraction_problem(where, name, spelled, info))
                return None
            if scale is None and offset is None:
                self.warnings.append(
                    f'{where}: {name} has unit {spelled!r}, which is not {target} unit we '
                    f'know; taken as {base_unit(wanted)} as it is (give its unit with '
                    'unit:, or scale: 1 if the value is right as it is)')
            return spelled, 1.0, 0.0, '', scale_f, offset_f
        if known.quantity != wanted:
            self.problems.append(
                f'{where}: {name} is in {spelled}, {QUANTITY_NAMES[known.quantity]}, not '
                f'{target}: map {target} signal (or, if the DBC\'s unit is wrong, give the '
                'right one with unit:)')
            return None
        if abs(scale_f) != 1.0:
            sample = _SAMPLE[wanted]
            raw = (sample - known.add) / known.factor
            self.problems.append(
                f'{where}: {name} is in {spelled}, which the device converts to '
                f'{base_unit(wanted)} itself; scale {scale_f:g} on top would make '
                f'{raw:g} {spelled} read {sample * scale_f + offset_f:g}. Remove scale '
                '(scale: -1 only flips the sign); if the DBC\'s unit is wrong, give the '
                'right one with unit:')
            return None
        converted = spelled if (known.factor, known.add) != (1.0, 0.0) else ''
        return spelled, known.factor, known.add, converted, scale_f, offset_f

    # --- battery_state ---------------------------------------------------------------------
    def scalar(self, key: str, spec: Any, where: str) -> Scalar | None:
        wanted = SCALAR_UNITS[key]
        if isinstance(spec, (int, float)) and not isinstance(spec, bool):
            return Scalar(constant=float(spec))
        if isinstance(spec, str):
            ref = self.ref(spec, where, wanted)
            return Scalar(ref=ref) if ref else None
        if not isinstance(spec, dict):
            self.problems.append(f'{where}: write a number, "Message.signal" or '
                                 '{signal: ..., scale: ..., offset: ...}')
            return None
        if 'reduce' in spec:
            op, of = spec.get('reduce'), spec.get('of')
            if op not in REDUCERS or of not in ('cell_voltage', 'cell_temperature'):
                self.problems.append(f'{where}: reduce must be one of {", ".join(REDUCERS)} '
                                     'and of one of cell_voltage, cell_temperature')
                return None
            fallback = None
            if 'fallback' in spec:
                fallback = self.scalar(key, spec['fallback'], where + '.fallback')
            return Scalar(reduce=op, of=of, fallback=fallback)
        self.unknown_keys(spec, {'signal', 'scale', 'offset', 'unit'}, where)
        ref = self.ref(spec.get('signal'), where, wanted, spec.get('scale'), spec.get('offset'),
                       spec.get('unit'))
        return Scalar(ref=ref) if ref else None

    def enum(self, key: str, spec: Any, where: str) -> Enum | None:
        enum_cls = ENUMS[key]
        if isinstance(spec, str) and '.' not in spec:
            value = self.enum_value(enum_cls, spec, where)
            return None if value is None else Enum(constant=value)
        rules = []
        for n, item in enumerate(spec if isinstance(spec, list) else [spec]):
            here = f'{where}[{n}]' if isinstance(spec, list) else where
            if not isinstance(item, dict) or 'signal' not in item:
                self.problems.append(f'{here}: write a {enum_cls.__name__} name or '
                                     '{signal: Message.signal, map: {value: NAME}, '
                                     'otherwise: NAME}')
                continue
            self.unknown_keys(item, {'signal', 'map', 'otherwise'}, here)
            ref = self.ref(item['signal'], here)
            if ref is None:
                continue
            info = self.messages[ref.message].signals[ref.signal]
            table: dict[float, int] = {}
            table_spec = item.get('map') or {}
            if not isinstance(table_spec, dict):
                self.problems.append(f'{here}.map: write {{value or value name: NAME}}')
                continue
            for raw_key, name in table_spec.items():
                raw = self.signal_value(info, raw_key, f'{here}.map')
                target = self.enum_value(enum_cls, name, f'{here}.map')
                if raw is not None and target is not None:
                    table[raw] = target
            otherwise = item.get('otherwise')
            if otherwise is not None:
                otherwise = self.enum_value(enum_cls, otherwise, f'{here}.otherwise')
            rules.append(EnumRule(ref, table, otherwise))
        return Enum(rules=tuple(rules))

    def enum_value(self, enum_cls: Any, name: Any, where: str) -> int | None:
        text = str(name).upper().removeprefix('POWER_SUPPLY_STATUS_').removeprefix(
            'POWER_SUPPLY_HEALTH_').removeprefix('POWER_SUPPLY_TECHNOLOGY_')
        if text in enum_cls.__members__:
            return int(enum_cls[text])
        self.problems.append(f'{where}: {name!r} is not a {enum_cls.__name__} name'
                             + dbc_codec.closest(text, list(enum_cls.__members__)))
        return None

    def signal_value(self, info: dbc_codec.SignalInfo, key: Any, where: str) -> float | None:
        """Read a map key or threshold: a number (physical) or a value name of the signal."""
        if isinstance(key, bool):
            self.problems.append(f'{where}: {key!r} read as a YAML boolean: quote the value '
                                 f'name of {info.name} ("ON", "NO", ...)')
            return None
        if isinstance(key, (int, float)):
            return float(key)
        names = {v: k for k, v in info.choices.items()}
        if isinstance(key, str) and key in names:
            return info.physical(names[key])
        self.problems.append(f'{where}: {key!r} is not a value name of {info.name}'
                             + (dbc_codec.closest(str(key), list(names)) if names else
                                ' (it has no VAL_ names: use numbers)'))
        return None

    # --- diagnostics -----------------------------------------------------------------------
    def levels(self, specs: Any) -> list[LevelRule]:
        rules: list[LevelRule] = []
        if not isinstance(specs, list):
            self.problems.append('diagnostics.levels: write a list of {signal, '
                                 f'{"|".join(CONDITIONS)}, level, message}}')
            return rules
        for n, spec in enumerate(specs):
            where = f'diagnostics.levels[{n}]'
            if not isinstance(spec, dict):
                self.problems.append(f'{where}: write {{signal, condition, level}}')
                continue
            self.unknown_keys(spec, {'signal', 'level', 'message', *CONDITIONS}, where)
            conditions = [c for c in CONDITIONS if c in spec]
            level = LEVELS.get(str(spec.get('level', '')).upper())
            if len(conditions) != 1 or level is None:
                self.problems.append(f'{where}: give one of {", ".join(CONDITIONS)} and a level'
                                     f' ({", ".join(LEVELS)})')
                continue
            condition = conditions[0]
            ref = self.ref(spec.get('signal'), where)
            if ref is None:
                continue
            info = self.messages[ref.message].signals[ref.signal]
            if condition.endswith('_bits'):
                threshold = self._mask(info, spec[condition], f'{where}.{condition}')
            else:
                threshold = self.signal_value(info, spec[condition], where)
            if threshold is None:
                continue
            message = spec.get('message') or f'{ref.name} {{value}} ({condition} ' \
                f'{spec[condition]})'
            rules.append(LevelRule(ref, condition, threshold, level, str(message)))
        return rules

    def _mask(self, info: dbc_codec.SignalInfo, mask: Any, where: str) -> float | None:
        """Check a bit mask: a positive whole number within the signal's raw bits."""
        if isinstance(mask, bool) or not isinstance(mask, int) or mask <= 0:
            self.problems.append(f'{where}: {mask!r} is not a bit mask (a whole number > 0, '
                                 'e.g. 0x0C)')
            return None
        if mask >> info.length:
            self.problems.append(f'{where}: 0x{mask:X} has bits beyond the {info.length} bits '
                                 f'of {info.name}')
            return None
        return float(mask)

    def values(self, spec: Any) -> list[Ref]:
        if spec in (None, 'all', 'none'):
            return []  # 'all': every signal of the consumed messages, at the end
        if not isinstance(spec, list):
            self.problems.append("diagnostics.values: write all, none or a list of "
                                 '"Message.signal" / "Message"')
            return []
        refs = []
        for text in spec:
            if isinstance(text, str) and '.' not in text:
                m = self.message(text, 'diagnostics.values')
                if m is not None:
                    refs += self.all_of(m)
            else:
                ref = self.ref(text, 'diagnostics.values', used=False)
                if ref is not None:
                    refs.append(ref)
        return refs

    def all_of(self, m: int) -> list[Ref]:
        """
        Return every signal of a message as diagnostics show it.

        The multiplexer's own signal and duplicated names are left out; multiplexed
        signals come after the others, in natural order (Cell_2 before Cell_10).
        """
        compiled = self.messages[m]
        muxed = compiled.mux_index is not None
        shown = [(i, s) for i, s in enumerate(compiled.signals)
                 if not s.is_multiplexer and DUPLICATE_MARK not in s.name]
        shown.sort(key=lambda item: (0, item[0]) if not item[1].mux_ids
                   else (1, natural_key(item[1].name)))
        return [Ref(m, i, s.mux_ids if muxed else None, f'{compiled.name}.{s.name}', s.unit)
                for i, s in shown]

    def unknown_keys(self, spec: dict, known: set[str], where: str) -> None:
        for key in spec:
            if key not in known:
                self.problems.append(f'{where}: unknown key {key!r}'
                                     + dbc_codec.closest(str(key), sorted(known)))
