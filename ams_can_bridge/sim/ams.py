# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Simulated Formula-Student AMS: the state machine, relays, cells, temperatures and SOC.

State machine (driven by frames the AMS receives)::

    IDLE --car ENABLE_SC--> SC_ENABLED --car ENABLE_TS--> PRECHARGING --precharge_time-->
    TS_ACTIVE --car ENABLE_DRIVE--> DRIVE
    IDLE --charger START--> INIT_CHARGING --init_charging_time--> PRECHARGING
         --precharge_time--> CHARGING;  charger STOP (any charging state) --> IDLE
    car ABORT (any state, ERROR included) --> IDLE

A command that does not fit the state is ignored (the master repeats ENABLE_* in every
heartbeat until answered). Errors: ``faults.error_code`` (once per new code), a cell
beyond its limits, or a bank-count mismatch (a car status or override bank count that differs
from the simulated bank count) send an AmsErrorEvent and enter ERROR (CHARGE_ERROR from a
charging state) with all relays open; only ABORT (or a charger STOP while charging) leaves it.

Heartbeat loss: in the car states (SC_ENABLED, the car's PRECHARGING, TS_ACTIVE, DRIVE) the
AMS opens its relays and returns to IDLE when no car status came for ``heartbeat_timeout``
(default 0.5 s, 10 missed 50 ms heartbeats). Charger commands (0x010) are periodic (100 ms):
a repeated START while charging is the charger keeping its request alive and changes
nothing. Charging states are not watched by default (the seed gives the AMS no charger
timeout, and a charger may send START once); set ``charger_timeout`` to return to IDLE when
the charger commands stop for that long.

``pad=True`` sends every frame padded to 8 bytes with 0x00, as AMS firmwares with a fixed
DLC do (the bridge must accept it: doc/protocols.md section 1). ``faults.malformed`` wins
over it (frames one byte short of their layout).

Relays (status word, 1 = closed): PRECHARGING closes AIR- and the precharge relay;
TS_ACTIVE, DRIVE and CHARGING close AIR- and AIR+; every other state opens all.

Physics: pack current from ``current_fn(now)`` (positive = discharge) in DRIVE, the charge
current (override 0x050, default 10 A) in CHARGING, zero otherwise; SOC integrates it over
``capacity_ah``; cell voltage = open-circuit voltage(SOC) - R x I + a fixed per-cell spread
(seeded) + ``faults.cell_drift_v`` on cell ``faults.drift_cell``; temperatures warm with I^2.
The AMS time tick (error events) counts milliseconds since start or the last SYNC_TIME.
"""
from __future__ import annotations

import math
import random
from typing import Callable

from ams_can_bridge.errors import ConfigError, ProtocolError
from ams_can_bridge.protocols import ams as proto
from ams_can_bridge.protocols.ams import (
    AmsChargerStatus, AmsCodec, AmsError, AmsErrorEvent, AmsState, AmsStatus, AmsStatusWord,
    CarCommand, CarStatus, CellTemperatures, CellVoltages, ChargerCommand, ChargerStart,
    DischargeTemperatures, OverrideBankCount, OverrideChargeCurrent)
from ams_can_bridge.protocols.common import Frame, TEMP_C_MAX
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge.sim.pack import Elapsed, integrate_soc, thermal_lag
from ams_can_bridge.sim.profiles import drive_current_a

CAR_STATES = (AmsState.SC_ENABLED, AmsState.TS_ACTIVE, AmsState.DRIVE)
CHARGE_STATES = (AmsState.INIT_CHARGING, AmsState.CHARGING)
ERROR_STATES = (AmsState.ERROR, AmsState.CHARGE_ERROR)
STATUS_PERIOD = 0.1
CELL_PERIOD = 1.0
CELL_R_OHM = 0.0015
CELL_HIGH_ERROR_V, CELL_LOW_ERROR_V = 4.25, 3.0
CELL_HIGH_WARN_V, CELL_LOW_WARN_V = 4.18, 3.3
TEMP_HIGH_ERROR_C, TEMP_LOW_ERROR_C, TEMP_WARN_C = 60.0, -10.0, 50.0
AMBIENT_C = 25.0
HEATING_C_PER_A2 = 0.001


def open_circuit_v(soc: float) -> float:
    """Open-circuit cell voltage of a Li-ion cell, roughly: 3.5 V empty, 4.15 V full."""
    return 3.5 + 0.65 * soc


class AmsSimulator(SimDevice):
    """
    AMS model for the simulator, the demo, tests and benchmarks (see the module docstring).

    Faults honoured: silent, malformed (every frame one byte short), error_code (an AmsError
    value), cell_drift_v / drift_cell, extra['stuck_counter'] (status counter stops),
    extra['imd_error'] (IMD error bit).
    """

    TYPE = 'ams'

    def __init__(self, name: str | None = None, base_id: int = proto.DEFAULT_BASE_ID,
                 bank_count: int = 1, current_fn: Callable[[float], float] | None = None,
                 seed: int = 0, *, capacity_ah: float = 20.0, initial_soc: float = 0.8,
                 charge_current_a: float = 10.0, precharge_time: float = 0.5,
                 init_charging_time: float = 0.2, heartbeat_timeout: float = 0.5,
                 charger_timeout: float | None = None, pad: bool = False) -> None:
        super().__init__(name)
        if not 1 <= bank_count <= proto.MAX_BANKS:
            raise ConfigError(f'bank_count = {bank_count}: allowed 1..{proto.MAX_BANKS}')
        self.codec = AmsCodec(base_id)
        self.bank_count = int(bank_count)
        self.current_fn = current_fn or drive_current_a
        self.capacity_ah = capacity_ah
        self.soc = initial_soc
        self.charge_current_a = charge_current_a
        self.precharge_time = precharge_time
        self.init_charging_time = init_charging_time
        self.heartbeat_timeout = heartbeat_timeout
        self.charger_timeout = charger_timeout
        self.pad = bool(pad)
        rng = random.Random(seed)
        cells = proto.CELLS_PER_BANK * self.bank_count
        self._cell_spread = [rng.uniform(-0.01, 0.01) for _ in range(cells)]
        self._temp_spread = [rng.uniform(-2.0, 2.0)
                             for _ in range(proto.TEMPS_PER_BANK * self.bank_count)]
        self._discharge_spread = [rng.uniform(0.0, 4.0) for _ in range(
            proto.DISCHARGE_TEMPS_PER_BANK * self.bank_count)]
        self.state = AmsState.IDLE
        self.counter = 0
        self.relay_error = (False, False, False)  # AIR-, AIR+, precharge at the last error
        self.last_error: AmsError | None = None
        self.heartbeat_losses = 0
        self.frames_ignored = 0  # received frames of our IDs that did not decode
        self.cell_v = [open_circuit_v(self.soc) + s for s in self._cell_spread]
        self.temperature_c = AMBIENT_C
        self._precharge_to = AmsState.TS_ACTIVE
        self._since = 0.0  # when the current state was entered
        self._last_car: float | None = None
        self._last_charger: float | None = None
        self._tick_origin = 0.0
        self._elapsed = Elapsed()
        self._injected: int | None = None
        self._limit_error: AmsError | None = None
        self._pending: list[Frame] = []  # event frames (errors) not yet sent
        self._status_now = True  # send a status at the next tick (a state change)
        self._status_periodic = Periodic(STATUS_PERIOD)
        self._charger_periodic = Periodic(STATUS_PERIOD, phase=STATUS_PERIOD / 2)
        self._cell_periodic = Periodic(CELL_PERIOD)

    # --- what other simulators read (the IVT-S in the same pack) ---------------------------
    def pack_current_a(self, now: float) -> float:
        """Pack current in A, positive = discharge: profile in DRIVE, charging < 0."""
        if self.state is AmsState.DRIVE:
            return float(self.current_fn(now))
        if self.state is AmsState.CHARGING and self.soc < 1.0:
            return -self.charge_current_a
        return 0.0

    def pack_voltage_v(self) -> float:
        """Pack voltage: the sum of the cells."""
        return math.fsum(self.cell_v)

    # --- state machine ---------------------------------------------------------------------
    def _enter(self, state: AmsState, now: float) -> None:
        if state is not self.state:
            self.state = state
            self._since = now
            self._status_now = True

    def _error(self, error: AmsError, now: float) -> None:
        relays = self._relays()
        self.relay_error = (relays[1], relays[0], relays[2])
        self.last_error = error
        charging = self.state in CHARGE_STATES or (
            self.state is AmsState.PRECHARGING and self._precharge_to is AmsState.CHARGING)
        self._enter(AmsState.CHARGE_ERROR if charging else AmsState.ERROR, now)
        tick = int(round((now - self._tick_origin) * 1000)) & 0xFFFF
        self._pending.append(self.codec.encode(AmsErrorEvent(error, tick)))

    def _relays(self) -> tuple[bool, bool, bool]:
        """AIR+, AIR-, precharge (True = closed) for the current state."""
        if self.state is AmsState.PRECHARGING:
            return False, True, True
        if self.state in (AmsState.TS_ACTIVE, AmsState.DRIVE, AmsState.CHARGING):
            return True, True, False
        return False, False, False

    def on_frame(self, frame: Frame, now: float) -> None:
        """Apply car status, charger commands and overrides addressed to this AMS."""
        if frame.is_extended_id or frame.arbitration_id not in self.codec.arbitration_ids:
            return
        try:
            message = self.codec.decode(frame.arbitration_id, frame.data)
        except ProtocolError:
            self.frames_ignored += 1
            return
        if isinstance(message, CarStatus):
            self._on_car_status(message, now)
        elif isinstance(message, ChargerCommand):
            self._on_charger_command(message, now)
        elif isinstance(message, OverrideChargeCurrent):
            self.charge_current_a = message.current_a
        elif isinstance(message, OverrideBankCount):
            if message.bank_count != self.bank_count and self.state not in ERROR_STATES:
                self._error(AmsError.BANK_COUNT_MISMATCH, now)

    def _on_car_status(self, message: CarStatus, now: float) -> None:
        self._last_car = now
        command, state = message.command, self.state
        if command is CarCommand.ABORT:
            self._enter(AmsState.IDLE, now)
            return
        if message.bank_count != self.bank_count:
            if state not in ERROR_STATES:
                self._error(AmsError.BANK_COUNT_MISMATCH, now)
            return
        if command is CarCommand.ENABLE_SC and state is AmsState.IDLE:
            self._enter(AmsState.SC_ENABLED, now)
        elif command is CarCommand.ENABLE_TS and state is AmsState.SC_ENABLED:
            self._precharge_to = AmsState.TS_ACTIVE
            self._enter(AmsState.PRECHARGING, now)
        elif command is CarCommand.ENABLE_DRIVE and state is AmsState.TS_ACTIVE:
            self._enter(AmsState.DRIVE, now)
        elif command is CarCommand.SYNC_TIME:
            self._tick_origin = now

    def _on_charger_command(self, message: ChargerCommand, now: float) -> None:
        self._last_charger = now
        charging = self.state in CHARGE_STATES + (AmsState.CHARGE_ERROR,) or (
            self.state is AmsState.PRECHARGING and self._precharge_to is AmsState.CHARGING)
        if message.start is ChargerStart.START and self.state is AmsState.IDLE:
            self._enter(AmsState.INIT_CHARGING, now)
        elif message.start is ChargerStart.STOP and charging:
            self._enter(AmsState.IDLE, now)

    def _advance_states(self, now: float) -> None:
        state, held = self.state, now - self._since
        car_path = state in CAR_STATES or (
            state is AmsState.PRECHARGING and self._precharge_to is AmsState.TS_ACTIVE)
        if car_path and (self._last_car is None
                         or now - self._last_car > self.heartbeat_timeout):
            self.heartbeat_losses += 1
            self._enter(AmsState.IDLE, now)  # relays open with the state
            return
        if (not car_path and self.charger_timeout is not None
                and state not in (AmsState.IDLE,) + ERROR_STATES
                and (self._last_charger is None
                     or now - self._last_charger > self.charger_timeout)):
            self._enter(AmsState.IDLE, now)
            return
        if state is AmsState.INIT_CHARGING and held >= self.init_charging_time:
            self._precharge_to = AmsState.CHARGING
            self._enter(AmsState.PRECHARGING, now)
        elif state is AmsState.PRECHARGING and held >= self.precharge_time:
            self._enter(self._precharge_to, now)

    def _check_faults(self, now: float) -> None:
        code = self.faults.error_code
        if code is not None and code != self._injected:
            self._injected = code
            if code not in set(map(int, AmsError)):
                raise ConfigError(f'faults.error_code = {code!r}: not an AMS error ID '
                                  f'(1..{len(AmsError)})')
            self._error(AmsError(code), now)
        self._injected = code
        limit = None
        high, low = max(self.cell_v), min(self.cell_v)
        if high > CELL_HIGH_ERROR_V:
            limit = AmsError.CELL_VOLTAGE_HIGH
        elif low < CELL_LOW_ERROR_V:
            limit = AmsError.CELL_VOLTAGE_LOW
        elif self.temperature_c > TEMP_HIGH_ERROR_C:
            limit = AmsError.CELL_TEMP_HIGH
        elif self.temperature_c < TEMP_LOW_ERROR_C:
            limit = AmsError.CELL_TEMP_LOW
        if limit is not None and limit is not self._limit_error \
                and self.state not in ERROR_STATES:
            self._error(limit, now)
        self._limit_error = limit

    # --- physics ---------------------------------------------------------------------------
    def _step(self, now: float) -> None:
        dt = self._elapsed(now)
        current = self.pack_current_a(now)
        self.soc = integrate_soc(self.soc, current, dt, self.capacity_ah, full=1.0)
        ocv = open_circuit_v(self.soc) - CELL_R_OHM * current
        self.cell_v = [ocv + s for s in self._cell_spread]
        if 0 <= self.faults.drift_cell < len(self.cell_v):
            self.cell_v[self.faults.drift_cell] += self.faults.cell_drift_v
        target = AMBIENT_C + HEATING_C_PER_A2 * current ** 2
        self.temperature_c = thermal_lag(self.temperature_c, target, dt)

    # --- frames ----------------------------------------------------------------------------
    def _word(self) -> AmsStatusWord:
        air_plus, air_minus, precharge = self._relays()
        high, low = max(self.cell_v), min(self.cell_v)
        return AmsStatusWord(
            air_plus=air_plus, air_minus=air_minus, precharge=precharge,
            warn_volt=high > CELL_HIGH_WARN_V or low < CELL_LOW_WARN_V,
            warn_temp=self.temperature_c > TEMP_WARN_C,
            imd_error=bool(self.faults.extra.get('imd_error')),
            ams_error=self.state in ERROR_STATES, bank_count=self.bank_count,
            state=self.state)

    @staticmethod
    def _wire_v(volts: float) -> float:
        """Quantize to 20 mV; the AMS's 8-bit field saturates at 0 and 5.1 V."""
        return min(255, max(0, round(volts / proto.CELL_VOLT_STEP))) * proto.CELL_VOLT_STEP

    @staticmethod
    def _wire_c(celsius: float, low: int = -128) -> int:
        # Temp_max (unsigned) ends at the protocol's 200 degC, a signed byte at 127
        return int(min(127 if low < 0 else TEMP_C_MAX, max(low, round(celsius))))

    def _status_frame(self) -> Frame:
        air_minus, air_plus, precharge = self.relay_error
        frame = self.codec.encode(AmsStatus(
            self._word(), self._wire_v(min(self.cell_v)),
            self._wire_c(max(self.temperatures()), 0), int(round(self.soc * 100)),
            self.counter, air_minus, air_plus, precharge))
        if not self.faults.extra.get('stuck_counter'):
            self.counter = (self.counter + 1) & 0xFF
        return frame

    def _charger_frame(self, now: float) -> Frame:
        current = min(25.5, max(0.0, -self.pack_current_a(now)))
        return self.codec.encode(AmsChargerStatus(
            self._word(), int(round(self.soc * 100)), round(current * 10) / 10,
            self.state is AmsState.CHARGING))

    def temperatures(self) -> list[float]:
        """Return the cell temperatures in degC (10 per bank)."""
        return [self.temperature_c + s for s in self._temp_spread]

    def _bank_frames(self) -> list[Frame]:
        frames = []
        temps = self.temperatures()
        balancing = 4.0 if self.state is AmsState.CHARGING else 0.0
        for bank in range(1, self.bank_count + 1):
            for group in range(proto.CELL_GROUPS):
                start = ((bank - 1) * proto.CELL_GROUPS + group) * proto.CELLS_PER_GROUP
                volts = self.cell_v[start:start + proto.CELLS_PER_GROUP]
                frames.append(self.codec.encode(
                    CellVoltages(bank, group, tuple(self._wire_v(v) for v in volts))))
            for group in range(proto.TEMP_GROUPS):
                start = ((bank - 1) * proto.TEMP_GROUPS + group) * proto.TEMPS_PER_GROUP
                values = temps[start:start + proto.TEMPS_PER_GROUP]
                frames.append(self.codec.encode(
                    CellTemperatures(bank, group, tuple(self._wire_c(t) for t in values))))
            for group in range(proto.TEMP_GROUPS):
                n = proto.DISCHARGE_TEMPS_PER_GROUP
                start = ((bank - 1) * proto.TEMP_GROUPS + group) * n
                values = [self.temperature_c + balancing + s
                          for s in self._discharge_spread[start:start + n]]
                frames.append(self.codec.encode(DischargeTemperatures(
                    bank, group, tuple(self._wire_c(t) for t in values))))
        return frames

    def tick(self, now: float) -> list[Frame]:
        """Advance the model to ``now``; return the frames due (empty while silent)."""
        self._step(now)
        self._advance_states(now)
        self._check_faults(now)
        frames, self._pending = self._pending, []
        periodic = self._status_periodic.due(now)
        if periodic or self._status_now:
            frames.append(self._status_frame())
            self._status_now = False
        if self._charger_periodic.due(now):
            frames.append(self._charger_frame(now))
        if self._cell_periodic.due(now):
            frames.extend(self._bank_frames())
        if self.faults.silent:
            return []
        if self.faults.malformed:
            frames = [self.corrupt(f) for f in frames]
        elif self.pad:
            frames = [Frame(f.arbitration_id, f.data.ljust(8, b'\x00'), f.is_extended_id)
                      for f in frames]
        return frames
