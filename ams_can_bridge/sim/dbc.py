"""
A simulated BMS for any dbc device: plausible traffic from a team's DBC and mapping.

``simulator --dbc FILE --mapping FILE``. The pack is a slow model (SoC drifting between
30 and 90 %, a current alternating between drive and recuperation, cells around the
open-circuit voltage with a small spread, temperatures warming and cooling); every mapped
signal carries its part of it, converted back from BatteryState units to the signal's DBC
unit (the inverse of the device's conversion) and encoded through cantools, strictly: a
value is clamped into the signal's [min|max] first, so every frame is in range. Signals the
mapping only reads for status, health or diagnostic levels carry a value that reads as
normal (a map entry to DISCHARGING/CHARGING/GOOD, a level's threshold not crossed); others
sit at 0 or their lowest value name. Each message is sent at its DBC cycle time
(GenMsgCycleTime; an event message, GenMsgSendType Event or cycle 0, is not sent), else the
primary every 0.1 s and the rest every 0.5 s; a multiplexed message sends all its branches
each period, a positioned array (AMS banks) every position.

Faults: ``silent``, ``malformed`` (one byte short), ``cell_drift_v`` on ``drift_cell``.
"""
from __future__ import annotations

import itertools
import math
from typing import Any

from ams_can_bridge.devices.base import PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.devices.dbc_mapping import load_plan
from ams_can_bridge.devices.dbc_plan import Array, Plan, Ref, resolve_path
from ams_can_bridge.protocols import dbc_codec
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.sim.base import Periodic, SimDevice

PRIMARY_PERIOD = 0.1  # s, when the DBC gives no cycle time
OTHER_PERIOD = 0.5
CAPACITY_AH = 20.0


class DbcSimulator(SimDevice):
    """Sends the messages a dbc mapping reads, with a slowly varying pack."""

    TYPE = 'dbc'

    def __init__(self, name: str | None = None, dbc_file: str = 'msg_defs/ams.dbc',
                 mapping_file: str = 'config/ams_dbc_mapping.yaml') -> None:
        """Load and check both files (MappingError); the defaults are our AMS example."""
        super().__init__(name)
        self.plan: Plan = load_plan(dbc_file, mapping_file)
        db = dbc_codec.load(str(resolve_path(dbc_file)))
        self.messages = [db.get_message_by_name(m.name) for m in self.plan.messages]
        self.periods: list[Periodic | None] = []
        for i, message in enumerate(self.messages):
            if message.cycle_time == 0 or message.send_type == 'Event':
                # an event message (the AMS error): not periodic
                self.periods.append(None)
                continue
            cycle = (message.cycle_time or 0) / 1000.0
            default = PRIMARY_PERIOD if i == self.plan.primary else OTHER_PERIOD
            self.periods.append(Periodic(cycle if cycle > 0 else default, phase=0.001 * i))
        cells = self.plan.arrays.get('cell_voltage')
        self.cells = cells.count if cells else 96
        self.roles = self._roles()
        self.t0: float | None = None

    # --- what each signal carries --------------------------------------------------------------
    def _roles(self) -> dict[tuple[int, int], tuple[str, Any]]:
        roles: dict[tuple[int, int], tuple[str, Any]] = {}
        plan = self.plan
        for key, scalar in plan.scalars.items():
            if scalar.ref is not None:
                roles[(scalar.ref.message, scalar.ref.signal)] = ('scalar', (key, scalar.ref))
            fallback = scalar.fallback
            while fallback is not None:
                if fallback.ref is not None:
                    roles[(fallback.ref.message, fallback.ref.signal)] = (
                        'scalar', (key, fallback.ref))
                fallback = fallback.fallback
        for key, array in plan.arrays.items():
            for n, ref in enumerate(array.refs):
                roles[(ref.message, ref.signal)] = ('element', (key, n, ref))
            for flag in array.invalid:
                if flag is not None:
                    roles[(flag.message, flag.signal)] = ('zero', None)
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

    @staticmethod
    def _to_signal(target: float, ref: Ref | Array) -> float:
        return (target - ref.add) / ref.factor if ref.factor else target

    def _value(self, m: int, i: int, info: dbc_codec.SignalInfo,
               pack: dict[str, float]) -> float:
        role, detail = self.roles.get((m, i), ('rest', None))
        if role == 'scalar':
            key, ref = detail
            return self._to_signal(pack[key], ref)
        if role == 'element':
            key, n, ref = detail
            return self._to_signal(self._element(key, n, pack), ref)
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
        if info.choices and role != 'zero':
            return info.physical(min(info.choices))
        return 0.0

    @staticmethod
    def _clamp(value: float, info: dbc_codec.SignalInfo) -> float:
        if info.minimum is not None:
            value = max(value, info.minimum)
        if info.maximum is not None:
            value = min(value, info.maximum)
        # onto the signal's grid, so cantools' strict encode takes it
        raw = round((value - info.offset) / info.scale)
        value = raw * info.scale + info.offset
        if info.minimum is not None and value < info.minimum:
            value += info.scale
        if info.maximum is not None and value > info.maximum:
            value -= info.scale
        return value

    # --- frames ----------------------------------------------------------------------------
    def _frames_of(self, m: int, pack: dict[str, float]) -> list[Frame]:
        compiled, message = self.plan.messages[m], self.messages[m]
        variants: list[dict[int, float]] = [{}]
        if compiled.mux_index is not None:
            mux_info = compiled.signals[compiled.mux_index]
            ids = sorted({v for s in compiled.signals for v in (s.mux_ids or ())})
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
                for j, i in enumerate(array.slot_signals):
                    key = next(k for k, a in self.plan.arrays.items() if a is array)
                    info = compiled.signals[i]
                    values[info.name] = self._clamp(self._to_signal(
                        self._element(key, base + j, pack), array), info)
            data = dbc_codec.encode(message, values)
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
            ranges.append([(i, float(v)) for v in range(low, min(high, low + 63) + 1)])
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
