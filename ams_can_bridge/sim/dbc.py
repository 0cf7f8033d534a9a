# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A simulated BMS for any dbc device: plausible traffic in the DBC's own units and meaning.

``simulator --dbc FILE --mapping FILE`` (or ``--profile NAME``). The pack is a slow model
(SoC drifting between 30 and 90 %, a current alternating between drive and recuperation,
cells around the open-circuit voltage with a small spread, temperatures warming and
cooling). Every mapped signal carries its part of it as the BMS would send it: in the
signal's DBC unit (an SoC signal in ``Percent`` carries 80.5, one in ``%`` with factor 0.1
the raw 805), whatever the mapping's conversion says, so a mapping that reads the BMS wrong
shows wrong values here too. Only the sign comes from the mapping (``scale: -1``: the BMS
counts discharge positive; no DBC says), and a signal whose unit this package does not know
from the mapping's own scale and offset. A validity flag carries the value its DBC value
table names Valid (else what the mapping's rule calls valid). Values are clamped into the
signal's [min|max] and raw bits and encoded through cantools, strictly.

Signals the mapping only reads for status, health or diagnostic levels carry a value that
reads as normal; others sit at raw 0 or their lowest value name. Each message is sent at its
DBC period (``GenMsgCycleTime``, the Orion utility's comment; an event message, ``Event`` or
cycle 0, is not sent), else the primary every 0.1 s and the rest every 0.5 s. A multiplexed
message with a DBC period sends one multiplexer value a frame, the period taken as its whole
rotation (as foxBMS 2 writes it: 5400 ms for 54 values at 100 ms), through the values the
mapping reads; without one, all of them each period. A positioned array (AMS banks) sends
every position each period.

Faults: ``silent``, ``malformed`` (one byte short), ``cell_drift_v`` on ``drift_cell``.
"""
from __future__ import annotations

import itertools
import math
from typing import Any

from ams_can_bridge.protocols.battery_state import PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.protocols.dbc_mapping.mapping import load_plan
from ams_can_bridge.protocols.dbc_mapping.plan import Array, ARRAY_UNITS, Plan, Ref, SCALAR_UNITS
from ams_can_bridge.protocols.dbc_mapping.units import lookup
from ams_can_bridge.protocols import dbc_codec, orion_bms2
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.dbc_load import cycle_time
from ams_can_bridge.sim.base import Periodic, SimDevice

PRIMARY_PERIOD = 0.1  # s, when the DBC gives no period
OTHER_PERIOD = 0.5
CAPACITY_AH = 20.0
AMS_EXAMPLE = ('msg_defs/ams.dbc', 'config/ams_dbc_mapping.yaml')


class DbcSimulator(SimDevice):
    """Sends the messages a dbc mapping reads, as the BMS of the DBC would."""

    TYPE = 'dbc'

    def __init__(self, name: str | None = None, dbc_file: str | None = None,
                 mapping_file: str | None = None, profile: str | None = None) -> None:
        """Load and check both files (MappingError); none given: our AMS example."""
        super().__init__(name)
        if not dbc_file and not profile:
            dbc_file, mapping_file = AMS_EXAMPLE
        self.plan: Plan = load_plan(dbc_file, mapping_file, profile)
        # a checksum byte the DBC cannot compute, set after encoding as the device sets it
        self.checksum_ids = frozenset(orion_bms2.CHECKSUM_IDS if profile == 'orion_bms2'
                                      else ())
        self.messages = self.plan.sources
        self.periods: list[Periodic | None] = []
        self.rotations: list[list[int]] = []  # multiplexer values sent one a frame
        self._next: list[itertools.cycle | None] = []
        for i, message in enumerate(self.messages):
            compiled = self.plan.messages[i]
            period, _ = cycle_time(message)
            if message.cycle_time == 0 or message.send_type == 'Event':
                self.periods.append(None)  # an event message (the AMS error): not periodic
                self._next.append(None)
                continue
            muxes = self._mux_values(i)
            if period and len(muxes) > 1:  # one value a frame, the period a whole rotation
                all_values = {v for s in compiled.signals for v in (s.mux_ids or ())}
                period /= len(all_values)
                self._next.append(itertools.cycle(muxes))
            else:
                self._next.append(None)
            default = PRIMARY_PERIOD if i == self.plan.primary else OTHER_PERIOD
            self.periods.append(Periodic(period or default, phase=0.001 * i))
        cells = self.plan.arrays.get('cell_voltage')
        self.cells = cells.count if cells else 96
        self.roles = self._roles()
        self.t0: float | None = None

    def _mux_values(self, m: int) -> list[int]:
        """Return the multiplexer values to send: those the mapping reads (else all)."""
        compiled = self.plan.messages[m]
        if compiled.mux_index is None:
            return []
        every = sorted({v for s in compiled.signals for v in (s.mux_ids or ())})
        read = sorted({v for (msg, i) in self.plan.mapped if msg == m
                       for v in (compiled.signals[i].mux_ids or ())})
        return read or every

    # --- what each signal carries --------------------------------------------------------------
    def _roles(self) -> dict[tuple[int, int], tuple[str, Any]]:
        roles: dict[tuple[int, int], tuple[str, Any]] = {}
        plan = self.plan
        for key, scalar in plan.scalars.items():
            while scalar is not None:
                if scalar.ref is not None:
                    roles[(scalar.ref.message, scalar.ref.signal)] = ('scalar', (key, scalar.ref))
                scalar = scalar.fallback  # type: ignore[assignment]
        for key, array in plan.arrays.items():
            for n, ref in enumerate(array.refs):
                roles[(ref.message, ref.signal)] = ('element', (key, n, ref))
            for flag in array.invalid:
                if flag is not None and array.flag_rule is not None:
                    roles[(flag.message, flag.signal)] = ('valid', array.flag_rule)
        for key, spec in plan.enums.items():
            wanted = {'power_supply_health': {int(PowerSupplyHealth.GOOD)},
                      'power_supply_status': {int(PowerSupplyStatus.DISCHARGING),
                                              int(PowerSupplyStatus.CHARGING)}}.get(key, set())
            for rule in spec.rules:
                if key == 'power_supply_status':  # follows the current's sign
                    roles.setdefault((rule.ref.message, rule.ref.signal), ('status', rule.table))
                    continue
                good = [v for v, target in rule.table.items() if target in wanted]
                roles.setdefault((rule.ref.message, rule.ref.signal),
                                 ('value', good[0] if good else None))
        for level in plan.levels:
            info = plan.messages[level.ref.message].signals[level.ref.signal]
            roles.setdefault((level.ref.message, level.ref.signal),
                             ('value', self._quiet(level.condition, level.threshold, info)))
        return roles

    def _quiet(self, condition: str, threshold: float,
               info: dbc_codec.SignalInfo) -> float | None:
        """Pick a value inside the signal's range that does not meet a level's condition."""
        if condition.endswith('_bits'):
            return info.physical(0)  # no bit set
        low = -math.inf if info.minimum is None else info.minimum
        high = math.inf if info.maximum is None else info.maximum
        candidates = {'equal': (threshold + info.scale, threshold - info.scale, low, high),
                      'not_equal': (threshold,),
                      'below': (threshold * 1.1 + 1, threshold, high),
                      'above': (threshold * 0.9 - 1, threshold, low)}[condition]
        for value in candidates:
            value = self._clamp(value, info)
            quiet = {'equal': value != threshold, 'not_equal': value == threshold,
                     'below': value >= threshold, 'above': value <= threshold}[condition]
            if quiet:
                return value
        return None

    def _pack(self, t: float) -> dict[str, float]:
        soc = 0.6 + 0.3 * math.sin(2 * math.pi * t / 600.0)
        current = -40.0 * math.sin(2 * math.pi * t / 20.0) - 10.0  # A, ROS sign
        ocv = 3.2 + 0.95 * soc
        return {'percentage': soc, 'current': current, 'ocv': ocv,
                'voltage': self.cells * (ocv + current * 0.0008),
                'temperature': 28.0 + 6.0 * math.sin(2 * math.pi * t / 300.0),
                'charge': soc * CAPACITY_AH, 'capacity': CAPACITY_AH,
                'design_capacity': CAPACITY_AH}

    def _element(self, key: str, n: int, pack: dict[str, float]) -> float:
        if key == 'cell_voltage':
            value = pack['ocv'] + pack['current'] * 0.0008 + 0.003 * math.sin(n * 1.7)
            if n == self.faults.drift_cell:
                value += self.faults.cell_drift_v
            return value
        return pack['temperature'] - 2.0 + 1.5 * math.sin(n * 0.9)

    def _to_signal(self, target: float, ref: Ref | Array, quantity: str) -> float:
        """
        Return what the BMS sends for a value in BatteryState's unit: in the DBC's unit.

        The sign is the mapping's (scale -1: the BMS counts discharge positive); a unit
        this package does not know is sent as the mapping converts it.
        """
        sample = ref.sample if isinstance(ref, Array) else ref
        unit = None
        if sample is not None:  # the DBC's own unit, not a unit: the mapping claims
            unit = lookup(self.plan.messages[sample.message].signals[sample.signal].unit)
        if sample is not None and unit is not None and unit.quantity == quantity:
            sign = -1.0 if sample.scale < 0 else 1.0
            return (sign * target - unit.add) / unit.factor
        factor, add = (ref.factor, ref.add)
        return (target - add) / factor if factor else target

    def _value(self, m: int, i: int, info: dbc_codec.SignalInfo,
               pack: dict[str, float]) -> float:
        role, detail = self.roles.get((m, i), ('rest', None))
        if role == 'scalar':
            key, ref = detail
            return self._to_signal(pack[key], ref, SCALAR_UNITS[key])
        if role == 'element':
            key, n, ref = detail
            return self._to_signal(self._element(key, n, pack), ref, ARRAY_UNITS[key])
        if role == 'valid':
            return self._valid(detail, info)
        if role == 'value' and detail is not None:
            value: float = detail  # the mapping's constant (a number)
            return value
        if role == 'status':
            want = (PowerSupplyStatus.DISCHARGING if pack['current'] < 0
                    else PowerSupplyStatus.CHARGING)
            keys: list[float] = [v for v, target in detail.items() if target == want] \
                or list(detail)
            if keys:
                return keys[0]
        if info.choices:
            return info.physical(min(info.choices))
        return info.physical(0)

    @staticmethod
    def _valid(rule: Any, info: dbc_codec.SignalInfo) -> float:
        """Return the flag value that means valid (the value table's, else the rule's)."""
        named = [info.physical(raw) for raw, text in info.choices.items()
                 if text.strip().lower() == 'valid']
        candidates = named + [info.physical(raw) for raw in sorted(info.choices)] + [
            info.physical(0), info.physical(1)]
        return next((v for v in candidates if not rule.invalid(v)), candidates[0])

    @staticmethod
    def _clamp(value: float, info: dbc_codec.SignalInfo) -> float:
        """Keep a value inside the signal's [min|max] and raw bits, on its grid."""
        if info.minimum is not None:
            value = max(value, info.minimum)
        if info.maximum is not None:
            value = min(value, info.maximum)
        low, high = ((-(1 << (info.length - 1)), (1 << (info.length - 1)) - 1)
                     if info.is_signed else (0, (1 << info.length) - 1))
        raw = min(max(round((value - info.offset) / info.scale), low), high)
        value = raw * info.scale + info.offset
        if info.minimum is not None and value < info.minimum and raw < high:
            value += info.scale
        if info.maximum is not None and value > info.maximum and raw > low:
            value -= info.scale
        return value

    # --- frames ----------------------------------------------------------------------------
    def _frames_of(self, m: int, pack: dict[str, float]) -> list[Frame]:
        compiled, message = self.plan.messages[m], self.messages[m]
        variants: list[dict[int, float]] = [{}]
        if compiled.mux_index is not None:
            mux_info = compiled.signals[compiled.mux_index]
            rotation = self._next[m]
            ids = [next(rotation)] if rotation is not None else self._mux_values(m)
            variants = [{compiled.mux_index: mux_info.physical(v)} for v in ids]
        slots = [a for a in self.plan.arrays.values() if a.slot_message == m]
        if slots:
            variants = [{**v, **p} for v in variants for p in self._positions(slots[0], m)]
        frames = []
        for fixed in variants:
            values: dict[str, float] = {}
            mux = fixed.get(compiled.mux_index) if compiled.mux_index is not None else None
            for i, info in enumerate(compiled.signals):
                if info.mux_ids and (mux is None or round(mux) not in info.mux_ids):
                    continue
                value = fixed[i] if i in fixed else self._value(m, i, info, pack)
                values[info.name] = self._clamp(value, info)
            for array in slots:
                base = self._base(array, fixed)
                key = next(k for k, a in self.plan.arrays.items() if a is array)
                for j, i in enumerate(array.slot_signals):
                    info = compiled.signals[i]
                    values[info.name] = self._clamp(self._to_signal(
                        self._element(key, base + j, pack), array, ARRAY_UNITS[key]), info)
            data = dbc_codec.encode(message, values)
            if compiled.frame_id in self.checksum_ids and len(data) == 8:
                data = orion_bms2.with_checksum(compiled.frame_id, data)
            frames.append(Frame(compiled.frame_id, data, compiled.is_extended_id))
        return frames

    @staticmethod
    def _base(array: Array, fixed: dict[int, float]) -> int:
        return int(sum((fixed[i] - first) * stride for i, first, stride in array.selectors))

    def _positions(self, array: Array, m: int) -> list[dict[int, float]]:
        """Every selector combination that lands inside the array (within DBC ranges)."""
        compiled = self.plan.messages[m]
        ranges = []
        for i, first, _ in array.selectors:
            info = compiled.signals[i]
            low = int(info.minimum if info.minimum is not None else first)
            high = int(info.maximum if info.maximum is not None else low + 63)
            high = min(high, low + max(63, array.count))
            ranges.append([(i, float(v)) for v in range(low, high + 1)])
        out = []
        for combo in itertools.product(*ranges):
            fixed = dict(combo)
            base = self._base(array, fixed)
            if 0 <= base and base + len(array.slot_signals) <= array.count:
                out.append(fixed)
        return out

    def tick(self, now: float) -> list[Frame]:
        """Return the messages due now (each DBC message at its own period)."""
        if self.t0 is None:
            self.t0 = now
        due = [m for m, period in enumerate(self.periods) if period and period.due(now)]
        if self.faults.silent or not due:
            return []
        pack = self._pack(now - self.t0)
        frames = [f for m in due for f in self._frames_of(m, pack)]
        if self.faults.malformed:
            frames = [self.corrupt(f) for f in frames]
        return frames
