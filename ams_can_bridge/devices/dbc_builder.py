"""
The checks of each entry of a dbc mapping, collecting every problem instead of stopping.

``devices.dbc_mapping`` walks the file (its top-level keys, primary, timeouts) and hands each
entry to a ``Builder``: a "Message.signal" reference (the closest names when it is not in the
DBC, the unit converted to what the field wants), a BatteryState scalar, enum or array
(templates, lists, positioned arrays), a diagnostics level or value list. docs/protocols.md
section 8 holds the rules.
"""
from __future__ import annotations

from typing import Any

from ams_can_bridge.devices.dbc_plan import (
    Array, ARRAY_UNITS, CONDITIONS, CONVERSIONS, Enum, EnumRule, ENUMS, LevelRule, LEVELS,
    REDUCERS, Ref, Scalar, SCALAR_UNITS, unit_text)
from ams_can_bridge.protocols import dbc_codec


class Builder:
    """Walks the mapping, collecting every problem instead of stopping at the first."""

    def __init__(self, db: Any, mapping: dict) -> None:
        self.db = db
        self.mapping = mapping
        self.problems: list[str] = []
        self.warnings: list[str] = []
        self.messages: list[dbc_codec.CompiledMessage] = []
        self._by_name: dict[str, int] = {}

    def message(self, name: str, where: str) -> int | None:
        if name in self._by_name:
            return self._by_name[name]
        try:
            msg = self.db.get_message_by_name(name)
        except KeyError:
            self.problems.append(f'{where}: message {name!r} is not in the DBC'
                                 + dbc_codec.closest(name, [m.name for m in self.db.messages]))
            return None
        self._by_name[name] = len(self.messages)
        self.messages.append(dbc_codec.compile_message(msg))
        return self._by_name[name]

    def ref(self, text: Any, where: str, wanted: str | None = None, scale: Any = None,
            offset: Any = None) -> Ref | None:
        if not isinstance(text, str) or text.count('.') != 1:
            self.problems.append(f'{where}: {text!r} is not "Message.signal"')
            return None
        msg_name, sig_name = text.split('.')
        m = self.message(msg_name, where)
        if m is None:
            return None
        compiled = self.messages[m]
        i = compiled.index.get(sig_name)
        if i is None:
            self.problems.append(f'{where}: signal {sig_name!r} is not in message {msg_name}'
                                 + dbc_codec.closest(sig_name, list(compiled.index)))
            return None
        info = compiled.signals[i]
        factor, add = self._conversion(info.unit, text, where, wanted, scale, offset)
        # nested multiplexing (decoded by cantools): one merged group per message
        mux = info.mux_ids if compiled.mux_index is not None else None
        return Ref(m, i, mux, text, info.unit, factor, add)

    def _conversion(self, unit: str, name: str, where: str, wanted: str | None,
                    scale: Any, offset: Any) -> tuple[float, float]:
        factor, add = 1.0, 0.0
        if wanted is not None:
            known = CONVERSIONS[wanted].get(unit_text(unit))
            if known is not None:
                factor, add = known
            elif scale is None:
                self.warnings.append(
                    f'{where}: {name} has unit {unit!r}, which is not a {wanted} unit we know;'
                    f' taken as {wanted} as it is (give a scale to silence this)')
        for label, value in (('scale', scale), ('offset', offset)):
            if value is not None and (isinstance(value, bool)
                                      or not isinstance(value, (int, float))):
                self.problems.append(f'{where}: {label} {value!r} is not a number')
                return factor, add
        scale = 1.0 if scale is None else float(scale)
        offset = 0.0 if offset is None else float(offset)
        return factor * scale, add * scale + offset

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
            if op not in REDUCERS or of not in ARRAY_UNITS:
                self.problems.append(f'{where}: reduce must be one of {", ".join(REDUCERS)} '
                                     f'and of one of {", ".join(ARRAY_UNITS)}')
                return None
            fallback = None
            if 'fallback' in spec:
                fallback = self.scalar(key, spec['fallback'], where + '.fallback')
            return Scalar(reduce=op, of=of, fallback=fallback)
        self.unknown_keys(spec, {'signal', 'scale', 'offset'}, where)
        ref = self.ref(spec.get('signal'), where, wanted, spec.get('scale'), spec.get('offset'))
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

    def array(self, key: str, spec: Any, where: str) -> Array | None:
        wanted = ARRAY_UNITS[key]
        if isinstance(spec, list):
            spec = {'signals': spec}
        if not isinstance(spec, dict):
            self.problems.append(f'{where}: write {{signal: "Msg.sig_{{i}}", count: N}} or a '
                                 'list of "Message.signal"')
            return None
        self.unknown_keys(spec, {'signal', 'signals', 'count', 'first', 'invalid',
                                 'per_frame', 'position', 'scale', 'offset'}, where)
        scale, offset = spec.get('scale'), spec.get('offset')
        if 'position' in spec:
            return self._slot_array(spec, where, wanted)
        if 'signals' in spec:
            names: list[Any] | None = list(spec['signals'] or [])
            invalid_names: list[Any] | None = [None] * len(spec['signals'] or [])
        else:
            count, first = spec.get('count'), spec.get('first', 0)
            if not isinstance(count, int) or isinstance(count, bool) or not 1 <= count <= 1024:
                self.problems.append(f'{where}.count: {count!r}: give the number of elements '
                                     '(1..1024)')
                return None
            names = self._expand(spec.get('signal'), count, first, where)
            invalid_names = (self._expand(spec['invalid'], count, first, where + '.invalid')
                             if spec.get('invalid') else [None] * count)
        if names is None or invalid_names is None:
            return None
        refs, invalid = [], []
        before = len(self.problems)
        for name, flag in zip(names, invalid_names):
            ref = self.ref(name, where, wanted, scale, offset)
            if ref is not None:
                refs.append(ref)
            invalid.append(self.ref(flag, where + '.invalid') if flag else None)
            if len(self.problems) - before >= 3:
                self.problems.append(f'{where}: (further elements not checked)')
                return None
        if len(self.problems) > before:
            return None
        return Array(count=len(refs), refs=tuple(refs), invalid=tuple(invalid))

    def _expand(self, template: Any, count: int, first: Any, where: str) -> list[str] | None:
        if not isinstance(template, str) or not isinstance(first, int):
            self.problems.append(f'{where}: signal must be a "Message.signal_{{i}}" template '
                                 'and first an integer')
            return None
        try:
            names = [template.format(i=first + n) for n in range(count)]
        except (KeyError, IndexError, ValueError) as exc:
            self.problems.append(f'{where}: template {template!r} does not resolve with {{i}}:'
                                 f' {exc!r}')
            return None
        if count > 1 and len(set(names)) == 1:
            self.problems.append(f'{where}: template {template!r} has no {{i}}')
            return None
        return names

    def _slot_array(self, spec: dict, where: str, wanted: str) -> Array | None:
        per_frame, count = spec.get('per_frame'), spec.get('count')
        position = spec.get('position')
        if not isinstance(per_frame, int) or not isinstance(count, int) \
                or not isinstance(position, dict) or not 1 <= count <= 1024:
            self.problems.append(f'{where}: a positioned array needs per_frame (elements per '
                                 'frame), count (1..1024) and position {selector signal: '
                                 '{stride: N, first: F}}')
            return None
        names = self._expand(spec.get('signal'), per_frame, spec.get('first', 0), where)
        if names is None:
            return None
        found = [self.ref(n, where, wanted, spec.get('scale'), spec.get('offset'))
                 for n in names]
        refs = [r for r in found if r is not None]
        if len(refs) != len(found):
            return None
        message = refs[0].message
        if any(r.message != message for r in refs):
            self.problems.append(f'{where}: a positioned array takes its elements from one '
                                 'message')
            return None
        selectors = []
        compiled = self.messages[message]
        for name, how in position.items():
            how = how if isinstance(how, dict) else {'stride': how}
            i = compiled.index.get(str(name))
            stride, first = how.get('stride'), how.get('first', 0)
            if i is None:
                self.problems.append(f'{where}.position: {name!r} is not a signal of '
                                     f'{compiled.name}'
                                     + dbc_codec.closest(str(name), list(compiled.index)))
            elif not isinstance(stride, int) or not isinstance(first, (int, float)):
                self.problems.append(f'{where}.position.{name}: stride must be an integer')
            else:
                selectors.append((i, float(first), stride))
        if len(selectors) != len(position):
            return None
        return Array(count=count, slot_message=message,
                     slot_signals=tuple(r.signal for r in refs), selectors=tuple(selectors),
                     factor=refs[0].factor, add=refs[0].add)

    # --- diagnostics -----------------------------------------------------------------------
    def levels(self, specs: Any) -> list[LevelRule]:
        rules: list[LevelRule] = []
        if not isinstance(specs, list):
            self.problems.append('diagnostics.levels: write a list of '
                                 '{signal, below|above|equal|not_equal, level, message}')
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
            ref = self.ref(spec.get('signal'), where)
            if ref is None:
                continue
            info = self.messages[ref.message].signals[ref.signal]
            threshold = self.signal_value(info, spec[conditions[0]], where)
            if threshold is None:
                continue
            message = spec.get('message') or f'{ref.name} {{value}} ({conditions[0]} ' \
                f'{spec[conditions[0]]})'
            rules.append(LevelRule(ref, conditions[0], threshold, level, str(message)))
        return rules

    def values(self, spec: Any) -> list[Ref]:
        if spec in (None, 'all'):
            return []  # filled with every signal of the consumed messages at the end
        if spec == 'none':
            return []
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
                ref = self.ref(text, 'diagnostics.values')
                if ref is not None:
                    refs.append(ref)
        return refs

    def all_of(self, m: int) -> list[Ref]:
        compiled = self.messages[m]
        return [Ref(m, i, s.mux_ids if compiled.mux_index is not None else None,
                    f'{compiled.name}.{s.name}', s.unit)
                for i, s in enumerate(compiled.signals)]

    def unknown_keys(self, spec: dict, known: set[str], where: str) -> None:
        for key in spec:
            if key not in known:
                self.problems.append(f'{where}: unknown key {key!r}'
                                     + dbc_codec.closest(str(key), sorted(known)))
