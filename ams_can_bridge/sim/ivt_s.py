"""
Simulated IVT-S shunt: all eight results every period, with consistent physics.

Pack side (positive = discharge, whatever the mounting): current from ``current_fn(now)``,
voltage from ``voltage_fn()`` (default: 400 V open circuit minus 50 mOhm x current),
charge = integral of current, energy = integral of U x I, temperature warming with I^2.
On the wire everything with a direction (I, W, As, Wh) carries the mounting sign: the
sensor measures current one way, and power / charge / energy follow from that current.
"""
from __future__ import annotations

from typing import Callable

from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.ivt_s import (
    DEFAULT_BASE_ID, DIVISOR, INT32_MAX, INT32_MIN, IvtMux, IvtResult, IvtSCodec)
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge.sim.pack import Elapsed, thermal_lag
from ams_can_bridge.sim.profiles import drive_current_a

AMBIENT_C = 25.0
HEATING_C_PER_A2 = 0.0008  # steady-state rise: 120 A -> about +11.5 degC


class IvtSSimulator(SimDevice):
    """
    IVT-S model for the simulator, the demo, tests and benchmarks.

    Faults honoured: silent, malformed (wrong DLC), error_code (any value: system error
    bit), extra['ocs'] (OCS bit), extra['result_error'] / extra['measurement_error'] (those
    bits on every result), extra['stuck_counter'] (counters stop advancing).
    """

    TYPE = 'ivt_s'

    def __init__(self, name: str | None = None, base_id: int = DEFAULT_BASE_ID,
                 byte_order: str = 'big', discharge_positive: bool = True,
                 current_fn: Callable[[float], float] | None = None,
                 voltage_fn: Callable[[], float] | None = None,
                 period: float = 0.1) -> None:
        super().__init__(name)
        self.codec = IvtSCodec(base_id, byte_order)
        self.discharge_positive = discharge_positive
        self.current_fn = current_fn or drive_current_a
        self.voltage_fn = voltage_fn
        self.open_circuit_v = 400.0
        self.internal_resistance_ohm = 0.05
        self.period = period
        self._periodic = Periodic(period)
        self._counters = [0] * len(IvtMux)
        self._elapsed = Elapsed()
        # Pack-side state, positive = discharge.
        self.current_a = 0.0
        self.voltage_v = self.open_circuit_v
        self.power_w = 0.0
        self.charge_as = 0.0
        self.energy_wh = 0.0
        self.temperature_c = AMBIENT_C

    def _step(self, now: float) -> None:
        dt = self._elapsed(now)
        self.current_a = float(self.current_fn(now))
        self.voltage_v = (float(self.voltage_fn()) if self.voltage_fn is not None else
                          self.open_circuit_v - self.internal_resistance_ohm * self.current_a)
        self.power_w = self.voltage_v * self.current_a
        # Rectangle rule on the sample just taken: the same sum a receiver can form from
        # the frames (I_k x dt_k), so tests can check the integration exactly.
        self.charge_as += self.current_a * dt
        self.energy_wh += self.power_w * dt / 3600.0
        target = AMBIENT_C + HEATING_C_PER_A2 * self.current_a ** 2
        self.temperature_c = thermal_lag(self.temperature_c, target, dt)

    def wire_values(self) -> dict[IvtMux, float]:
        """Return the SI values as the sensor reports them (mounting sign applied)."""
        sign = 1.0 if self.discharge_positive else -1.0
        return {
            IvtMux.I: sign * self.current_a,
            IvtMux.U1: self.voltage_v,
            IvtMux.U2: self.voltage_v,  # measured after the contactors: closed here
            IvtMux.U3: 0.0,  # unused input
            IvtMux.T: self.temperature_c,
            IvtMux.W: sign * self.power_w,
            IvtMux.AS: sign * self.charge_as,
            IvtMux.WH: sign * self.energy_wh,
        }

    def tick(self, now: float) -> list[Frame]:
        """Frames due at ``now``: the eight results, every ``period``."""
        if not self._periodic.due(now):
            return []
        self._step(now)
        if self.faults.silent:
            return []
        extra = self.faults.extra
        flags = dict(ocs=bool(extra.get('ocs')),
                     result_error=bool(extra.get('result_error')),
                     measurement_error=bool(extra.get('measurement_error')),
                     system_error=self.faults.error_code is not None)
        frames = []
        for kind, value in self.wire_values().items():
            result = IvtResult.from_value(kind, value, counter=self._counters[kind], **flags)
            if not INT32_MIN <= result.raw <= INT32_MAX:  # saturate like a real sensor
                raw = INT32_MAX if result.raw > 0 else INT32_MIN
                result = IvtResult(kind, result.counter, result.ocs, True,
                                   result.measurement_error, result.system_error, raw,
                                   raw / DIVISOR[kind])
            if not extra.get('stuck_counter'):
                self._counters[kind] = (self._counters[kind] + 1) & 0x0F
            frame = self.codec.encode(result)
            frames.append(self.corrupt(frame) if self.faults.malformed else frame)
        return frames
