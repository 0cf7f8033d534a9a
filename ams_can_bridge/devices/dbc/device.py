# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Any BMS from its DBC: a team's DBC and a short mapping -> BatteryState and diagnostics.

doc/protocols.md section 8, doc/own_bms.md. The mapping (``protocols.dbc_mapping.mapping``)
is checked whole at start; the device consumes exactly the messages it references. Each
frame is decoded by the compiled decoder of its message (``protocols.dbc_codec``) and kept
whole, with the time it came, as its *group* (a multiplexed message: one group per
multiplexer value). Every group expires on its own after its message's timeout (the
mapping's, else a few DBC periods, else ``stale_timeout``): its values are unknown (NaN)
again, never an old number shown as live, and the device WARNs naming what is missing
(``devices.dbc.diagnostics``). A frame of the primary message makes one BatteryState; while it is
silent the device is STALE as every other device.

A value outside its DBC [min|max], or an element whose validity flag says invalid, is NaN
and the frame counts as malformed (the rest of the frame is used). Telemetry only.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Iterable, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, Device, DiagnosticReport, Level, NAN, PowerSupplyHealth,
    PowerSupplyStatus)
from ams_can_bridge.devices.generated_configs import DbcConfig
from ams_can_bridge.devices.dbc.describe import start_lines
from ams_can_bridge.devices.dbc.diagnostics import (
    capped_values, listed, missing_report, WARNINGS_CAP)
from ams_can_bridge.protocols.dbc_mapping.mapping import given_timeouts, load_plan
from ams_can_bridge.protocols.dbc_mapping.plan import (
    Array, Enum, FlagRule, LEARNED_PERIODS, MappingError, OUTLIER, Plan, Ref, Scalar)
from ams_can_bridge.protocols.dbc_profiles import PROFILES
from ams_can_bridge.protocols.dbc_mapping.units import unit_text
from ams_can_bridge.devices.timed import TimedSpans, TimedStore
from ams_can_bridge.errors import ConfigError, ProtocolError
from ams_can_bridge.protocols import dbc_codec
from ams_can_bridge.parameters import ParamSpec

_GroupKey = tuple[int, Any]


def _fmt(value: float | None, choices: Mapping[int, str] | None = None) -> str:
    if value is None or value != value:
        return 'unknown'
    if choices and value == int(value) and int(value) in choices:
        return f'{choices[int(value)]} ({int(value)})'
    return f'{value:g}'


class DbcDevice(Device[DbcConfig]):
    """A BMS described by a DBC and a mapping file (telemetry only)."""

    TYPE = 'dbc'
    Config = DbcConfig
    BROADCAST_PERIOD = 0.2  # default stale_timeout 1 s; set it to ~5 x your primary's period
    DEFAULT_BASE_ID = None
    PARAMS = [
        ParamSpec('dbc_file', str, None,
                  'path of the BMS DBC (absolute, or relative to the working directory, '
                  'the params file\'s folder, then the package share folder)'),
        ParamSpec('mapping_file', str, None,
                  'path of the mapping YAML (DBC signals -> BatteryState, diagnostics); '
                  'relative paths as dbc_file'),
        ParamSpec('profile', str, '',
                  "a shipped, tested DBC and mapping instead of dbc_file and mapping_file "
                  "(mapping_file, when given, replaces the profile's mapping)",
                  choices=('', *PROFILES)),
        ParamSpec('timeouts', 'str[]', [],
                  "'Message=seconds' per message: how long its values stay fresh, over the "
                  "mapping's timeouts and the DBC's periods (probe writes what it heard; "
                  'the device also learns each period from the traffic)', max_length=1024),
    ]

    def __init__(self, name: str, config: DbcConfig | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, config, clock)
        try:
            self.plan: Plan = load_plan(self.config.dbc_file, self.config.mapping_file,
                                        self.config.profile)
        except MappingError as exc:
            raise ConfigError(str(exc)) from None  # its lines as they are: YAML's own too
        plan = self.plan
        given_timeouts(plan, self.config.timeouts)
        self.warnings = list(plan.warnings)  # the mapping's
        self.dbc_notes = list(plan.dbc_notes)  # what the DBC lacked: dropped lines, broken
        self.started = clock()  # missing data counts from here (log2bag: its first frame)
        self._by_id = {m.frame_id: (i, m) for i, m in enumerate(plan.messages)}
        self._frame_ids = frozenset((m.frame_id, m.is_extended_id) for m in plan.messages)
        if len(self._by_id) != len(self._frame_ids):
            raise ConfigError('the mapping uses one CAN ID as a standard and an '
                              'extended message: map only one of them')
        self.groups: TimedStore[_GroupKey, tuple] = TimedStore()
        # (message, signal) -> the last implausible value refused, and when
        self.implausible: dict[tuple[int, int], tuple[str, float]] = {}
        self._stamp = NAN
        # validity flags per message: (flag signal index, its rule, element label) for the
        # malformed count
        self._flags: dict[int, list[tuple[int, FlagRule, str]]] = {}
        for key, array in plan.arrays.items():
            for n, flag in enumerate(array.invalid):
                if flag is not None and array.flag_rule is not None:
                    self._flags.setdefault(flag.message, []).append(
                        (flag.signal, array.flag_rule, f'{key}[{n}] ({flag.name})'))
        # positioned arrays: each element timed on its own (a span of one)
        self._slots: dict[int, list[tuple[str, Array, TimedSpans]]] = {}
        for key, array in plan.arrays.items():
            if array.slot_message is not None:
                self._slots.setdefault(array.slot_message, []).append(
                    (key, array, TimedSpans.uniform(1, array.count)))
        # per message, what its traffic taught (see _learn): [last arrival, period, outliers
        # in a row, learned timeout, first arrival, groups seen, groups seen twice]
        self.rates = [[NAN, NAN, 0, 0.0, NAN, 1, 0] for _ in plan.messages]
        # per message (multiplexed or positioned): group (mux value or position) -> arrivals
        # (counted up to 2)
        self.arrivals: list[dict[Any, int]] = [{} for _ in plan.messages]
        # per CAN ID, all the receive thread needs: (message, group key, invalid flags,
        # positioned arrays, primary?, its rate, its arrivals)
        self._handlers = {
            m.frame_id: (m, (i, None), self._flags.get(i, []), self._slots.get(i, []),
                         i == plan.primary, self.rates[i], self.arrivals[i])
            for i, m in enumerate(plan.messages)}

    @property
    def frame_ids(self) -> frozenset[tuple[int, bool]]:
        """Return exactly the (CAN ID, 29-bit) of the messages the mapping references."""
        return self._frame_ids

    @property
    def arbitration_ids(self) -> frozenset[int]:
        """Return the CAN IDs of the messages the mapping references."""
        return frozenset(self._by_id)

    @property
    def is_extended_id(self) -> bool:
        """Tell whether every message the mapping references is 29-bit (no single codec)."""
        return bool(self._frame_ids) and all(extended for _, extended in self._frame_ids)

    # --- bus thread ------------------------------------------------------------------------
    def handle_frame(self, arbitration_id: int, data: bytes, stamp: float) -> bool:
        """Decode one frame into its group; True for the primary message."""
        entry = self._handlers.get(arbitration_id)
        if entry is None:
            return False
        compiled, key, flags, slots, primary, rate, arrivals = entry
        try:
            values, bad = compiled.decode(data)
        except ProtocolError as exc:
            with self.lock:
                self._count_malformed(str(exc))
            return False
        now = self.clock()
        with self.lock:
            if self.started != self.started:  # log2bag: the clock is the log's, from here
                self.started = now
            self.frames_received += 1
            if bad or flags:
                self._check(compiled, key[0], arbitration_id, data, values, bad, flags, now)
            old = None if compiled.compiled else self.groups.latest(key)
            if old is not None:
                # nested multiplexing: each frame carries one branch; keep the others' last
                values = tuple(o if v is None else v for v, o in zip(values, old))
            self.groups.put(key, values, now)
            group = None
            if compiled.mux_index is not None:
                mux = values[compiled.mux_index]
                if mux == mux:
                    info = compiled.signals[compiled.mux_index]
                    group = round((mux - info.offset) / info.scale)
                    self.groups.put((key[0], group), values, now)
            if slots:
                group = self._put_slots(slots, values, now)
            if group is not None and arrivals.get(group, 0) < 2:
                self._arrived(rate, arrivals, group)
            last, rate[0] = rate[0], now
            if last == last:
                # learn the period (see _learn), inline: this runs for every frame
                interval, period = now - last, rate[1]
                if interval <= OUTLIER * period and not rate[2]:
                    rate[1] = period = period + (interval - period) * 0.25
                    rate[3] = LEARNED_PERIODS * period * rate[5]
                else:
                    self._learn(rate, interval)
            else:
                rate[4] = now
            if primary:
                self._stamp = stamp
                self.last_seen = now
            return primary

    def _check(self, compiled: Any, m: int, arbitration_id: int, data: bytes, values: tuple,
               bad: Any, flags: list[tuple[int, FlagRule, str]], now: float) -> None:
        """Count a frame with a value out of range or a flag saying invalid (lock held)."""
        problems = [self._out_of_range(compiled, m, i, data, now) for i in bad]
        # a flag of another multiplexer branch is absent (None): not this frame's
        problems += [f'{label} flagged invalid' for flag, rule, label in flags
                     if values[flag] is not None and rule.invalid(values[flag])]
        if problems:
            self._count_malformed(f'{compiled.name} 0x{arbitration_id:X}: '
                                  + ', '.join(problems))

    def _out_of_range(self, compiled: Any, m: int, i: int, data: bytes, now: float) -> str:
        """
        Say why a signal's value was refused: outside its DBC range, or implausible.

        An implausible value (beyond the bounds of the field it is mapped to, or not a
        finite number) is kept to be named in the diagnostics (the decoder gave NaN: the
        value is read again here, only for a refused frame).
        """
        info = compiled.signals[i]
        bound = self.plan.bounds.get((m, i))
        try:
            value = float(self.plan.sources[m].decode(
                bytes(data[:compiled.length]), decode_choices=False)[info.name])
        except Exception:  # a branch cantools cannot read: say the range only
            return f'{info.name} outside its DBC range'
        if bound is None or (math.isfinite(value) and not dbc_codec.in_range(info, value)):
            return f'{info.name} outside its DBC range'
        unit = f' {unit_text(info.unit)}' if info.unit else ''
        text = f'{compiled.name}.{info.name} = {value:g}{unit} (implausible for {bound})'
        self.implausible[(m, i)] = (text, now)
        return text

    @staticmethod
    def _arrived(rate: list, arrivals: dict[Any, int], group: Any) -> None:
        """Count a group's first and second arrival (lock held; see all_arrived_twice)."""
        count = arrivals.get(group, 0)
        arrivals[group] = count + 1
        if count:
            rate[6] += 1
        else:
            rate[5] = len(arrivals)

    @staticmethod
    def _learn(rate: list, interval: float) -> None:
        """
        Learn a message's period from the time between its frames (lock held).

        A smoothed interval; one far longer than the period so far (OUTLIER x: the sender
        paused, the bus was lost) is not learned unless the next ones are as long (the
        sender was set to a slower rate). The learned timeout is LEARNED_PERIODS x that
        period x the groups of a rotation: a message's values never expire between its
        frames, whatever rate the vendor's utility set.
        """
        period = rate[1]
        if period != period or rate[2] >= 2:
            rate[1], rate[2] = interval, 0
        elif interval <= OUTLIER * period:
            rate[1], rate[2] = period + (interval - period) * 0.25, 0
        else:
            rate[2] += 1
            return
        rate[3] = LEARNED_PERIODS * rate[1] * rate[5]

    @staticmethod
    def _put_slots(slots: list, values: tuple, now: float) -> int | None:
        """Put a positioned frame's elements; return its position (None: not placed)."""
        placed = None
        for _, array, elements in slots:
            position = 0.0
            for i, first, stride in array.selectors:
                selector = values[i]
                if selector is None or selector != selector:
                    break
                position += (selector - first) * stride
            else:
                base = int(position)
                signals = array.slot_signals
                low, high = max(0, -base), min(len(signals), array.count - base)
                if low < high:
                    factor, add = array.factor, array.add
                    elements.put_elements(base + low, [
                        NAN if values[i] is None else values[i] * factor + add
                        for i in signals[low:high]], now)
                    if placed is None:
                        placed = base
        return placed

    # --- reports: what the engine publishes (lock held) ---------------------------------------
    def group_timeout(self, message: int) -> float:
        """Return how long a message's groups stay fresh (s): never below what it taught."""
        return max(self.plan.timeouts.get(message, self.stale_timeout),
                   self.rates[message][3])

    def all_arrived_twice(self, message: int) -> bool:
        """
        Tell whether every group heard of a message has come twice (lock held).

        A group (multiplexer value, position) not heard by then is missing: its sender is
        silent, not late.
        """
        rate = self.rates[message]
        return bool(self.arrivals[message]) and rate[6] >= rate[5]

    def learned_periods(self) -> dict[str, float]:
        """Return the period each message was heard at (s), by message name (lock held)."""
        return {m.name: rate[1] for m, rate in zip(self.plan.messages, self.rates)
                if rate[1] == rate[1]}

    def slot_elements(self, key: str) -> TimedSpans:
        """Return the timed elements of a positioned array."""
        array = self.plan.arrays[key]
        assert array.slot_message is not None
        return next(e for k, _, e in self._slots[array.slot_message] if k == key)

    def _fresh(self, key: _GroupKey, now: float) -> tuple | None:
        return self.groups.get(key, now, self.group_timeout(key[0]))

    def raw(self, ref: Ref, now: float) -> float:
        """Return the physical DBC value of a signal (NaN: unknown, expired, not in range)."""
        if ref.mux is None:
            values = self._fresh((ref.message, None), now)
        else:
            # the most recent of the branches the reference names, if fresh
            newest = max(((ref.message, mux) for mux in ref.mux), key=self.groups.seen,
                         default=None)
            values = (None if newest is None
                      else self.groups.get(newest, now, self.group_timeout(ref.message)))
        if values is None:
            return NAN
        value = values[ref.signal]
        return NAN if value is None else value

    def _value(self, ref: Ref, now: float) -> float:
        return self.raw(ref, now) * ref.factor + ref.add

    def _array(self, key: str, now: float) -> list[float]:
        array = self.plan.arrays[key]
        if array.slot_message is not None:
            return self.slot_elements(key).read(now, self.group_timeout(array.slot_message))
        out = []
        rule = array.flag_rule
        for ref, flag in zip(array.refs, array.invalid):
            value = self._value(ref, now)
            if flag is not None and rule is not None and rule.invalid(self.raw(flag, now)):
                value = NAN  # invalid, or the flag unknown: no data
            out.append(value)
        return out

    def _scalar(self, scalar: Scalar, arrays: dict[str, list[float]], now: float) -> float:
        if scalar.constant is not None:
            return scalar.constant
        if scalar.ref is not None:
            return self._value(scalar.ref, now)
        data = arrays.get(scalar.of, [])
        known = [v for v in data if v == v]
        if scalar.reduce == 'sum':
            result = math.fsum(data) if data else NAN  # any unknown element: unknown sum
        elif not known:
            result = NAN
        elif scalar.reduce == 'max':
            result = max(known)
        elif scalar.reduce == 'min':
            result = min(known)
        else:
            result = math.fsum(known) / len(known)
        if result != result and scalar.fallback is not None:
            return self._scalar(scalar.fallback, arrays, now)
        return result

    def _enum(self, spec: Enum, now: float) -> int | None:
        if spec.constant is not None:
            return spec.constant
        for rule in spec.rules:
            value = self.raw(rule.ref, now)
            if value != value:
                continue
            found = rule.table.get(value, rule.otherwise)
            if found is not None:
                return found
        return None

    def _fields(self, now: float) -> tuple[dict[str, list[float]], dict[str, float]]:
        arrays = {key: self._array(key, now) for key in self.plan.arrays}
        scalars = {key: self._scalar(scalar, arrays, now)
                   for key, scalar in self.plan.scalars.items()}
        return arrays, scalars

    def _battery_report(self) -> BatteryReport:
        now, plan = self.clock(), self.plan
        arrays, scalars = self._fields(now)
        report = BatteryReport(stamp=self._stamp, present=self.last_seen is not None,
                               cell_voltage=arrays.get('cell_voltage', []),
                               cell_temperature=arrays.get('cell_temperature', []))
        for key, value in scalars.items():
            setattr(report, key, value)
        for key, spec in plan.enums.items():
            found = self._enum(spec, now)
            if found is not None:
                setattr(report, key, found)
        if 'power_supply_status' not in plan.enums or \
                report.power_supply_status == PowerSupplyStatus.UNKNOWN:
            report.power_supply_status = current_status(report.current)
        if 'power_supply_health' not in plan.enums:
            report.power_supply_health = PowerSupplyHealth.UNKNOWN
        return report

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        now, plan = self.clock(), self.plan
        if self.started != self.started:
            self.started = now
        level, parts = Level.OK, []
        for rule in plan.levels:
            value = self.raw(rule.ref, now)
            info = plan.messages[rule.ref.message].signals[rule.ref.signal]
            if value == value and rule.hit(value, info):
                level = rule.level
                bits = round((value - info.offset) / info.scale) & int(rule.threshold) \
                    if rule.condition.endswith('_bits') else 0
                parts.append(rule.message.format(value=_fmt(value, info.choices),
                                                 signal=rule.ref.name, bits=f'0x{bits:X}'))
                break
        missing = missing_report(self, *self._fields(now), now)
        if missing:
            level = max(level, Level.WARN)
            parts += missing
        odd = [text for (m, _), (text, seen) in self.implausible.items()
               if now - seen <= self.group_timeout(m)]
        if odd:
            level = max(level, Level.WARN)
            parts.append('implausible: ' + ', '.join(odd) + ' (not published)' + (
                f"; the BMS may not send profile {self.config.profile}'s layout (messages "
                "customised in its utility?): give your own DBC and mapping"
                if self.config.profile and not self.config.mapping_file else ''))
        if self.warnings:
            level = max(level, Level.WARN)
            parts.append(f'{len(self.warnings)} mapping warning(s)')
        # The DBC's notes are of parts the mapping does not use (a mapped broken message or
        # duplicated name stops the start): said once in the start log, never a level.
        _, silent = self.groups.split(now, lambda key: self.group_timeout(key[0]))
        expired = sorted({plan.messages[m].name for m, mux in silent if mux is None})
        if expired:
            parts.append('silent: ' + ', '.join(expired))
        if not parts:
            parts.append('OK')
        values: dict[str, str] = {}
        if with_values:
            values = capped_values(plan, lambda ref: _fmt(
                self.raw(ref, now), plan.messages[ref.message].signals[ref.signal].choices))
            values.update({f'unknown {n + 1}': text for n, text in enumerate(missing)})
            values.update(listed('mapping warning', self.warnings))
            values.update(listed('DBC note', self.dbc_notes))
            if expired:
                values['messages expired'] = ', '.join(expired)
        return DiagnosticReport(level, '; '.join(parts), values)

    def start_log(self) -> tuple[list[str], list[str]]:
        """Return the start log of this device: how each field is computed, the warnings."""
        notes = self.dbc_notes[:WARNINGS_CAP]
        if len(self.dbc_notes) > WARNINGS_CAP:
            notes.append(f'... and {len(self.dbc_notes) - WARNINGS_CAP} more DBC warnings '
                         '(parts of the DBC the mapping does not use)')
        info = start_lines(self.plan, self.stale_timeout) + self.plan.dbc_info
        return info, self.warnings + notes

    def config_problems(self, config: DbcConfig,
                        keys: Iterable[str] | None = None) -> list[str]:
        """Files are checked when the plan loads (every problem at once, see __init__)."""
        return []
