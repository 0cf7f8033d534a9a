# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Simulated ZEVA BMS16: status, cells and SMA frames at 4 Hz; takes config and commands.

A LiFePO4 pack (up to 16 cells in series) whose SoC follows the current profile. Reacts like
the real BMS16 (doc/protocols.md section 4): 504/505 store the configuration (values
restricted to the vendor's ranges, as the device does), 506 clears the error, 507 sets SoC
to 100 %, 508 powers it off (silent until ``power_on()``, as a real unit stays off until its
supply is cycled). The standard form (EVMS3 protocol) is ``sim.bms16_std``.
"""
from __future__ import annotations

import bisect
import random
from typing import Any, Callable

from ams_can_bridge.protocols.bms16 import (
    AcknowledgeError, Bms16Cells, Bms16Codec, Bms16ConfigPart1, Bms16ConfigPart2, Bms16Error,
    Bms16Status, CELL_FRAME_COUNT, CELL_FRAME_FIRST, CELL_MAX_RAW, CONFIG_1, CONFIG_2,
    CONFIG_FIELD, PowerOff, ResetSoc, SETTINGS, SHUNT_SIZES_A)
from ams_can_bridge.errors import MalformedFrameError, ProtocolError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.sma import (
    SmaAlarms, SmaBattery, SmaCodec, SmaFlag, SmaLimits, SmaSoc)
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge.sim.pack import Elapsed, integrate_soc, thermal_lag
from ams_can_bridge.sim.profiles import drive_current_a

# LiFePO4 open-circuit voltage per cell against SoC (%): flat middle, steep ends.
_OCV_SOC = (0.0, 5.0, 10.0, 30.0, 60.0, 90.0, 98.0, 100.0)
_OCV_V = (2.80, 3.10, 3.20, 3.26, 3.30, 3.34, 3.40, 3.50)
CELL_RESISTANCE_OHM = 0.0005


def lfp_cell_ocv(soc_pct: float) -> float:
    """Open-circuit voltage of one LiFePO4 cell at soc_pct (linear between table points)."""
    soc = min(100.0, max(0.0, soc_pct))
    i = min(len(_OCV_SOC) - 1, max(1, bisect.bisect_left(_OCV_SOC, soc)))
    s0, s1, v0, v1 = _OCV_SOC[i - 1], _OCV_SOC[i], _OCV_V[i - 1], _OCV_V[i]
    return v0 + (v1 - v0) * (soc - s0) / (s1 - s0)


def _clamped(name: str, value: float) -> float:
    spec = CONFIG_FIELD[name]
    assert spec.low is not None and spec.high is not None  # every BMS16 setting has a range
    return min(spec.high, max(spec.low, value))


def sma_empty(frame: Frame) -> Frame:
    """Return the frame without data: malformed for every SMA ID (a dropped byte may not be)."""
    return Frame(frame.arbitration_id, b'', frame.is_extended_id)


def pack_cells(sim: Any) -> list[float]:
    """Cell voltages (V, unclamped) of a BMS16 simulator: OCV, IR drop, offsets, drift fault."""
    base = lfp_cell_ocv(sim.soc_pct) - sim.current_a * CELL_RESISTANCE_OHM
    volts = [base + sim.cell_offsets_v[k] for k in range(sim.cells)]
    if 0 <= sim.faults.drift_cell < sim.cells:
        volts[sim.faults.drift_cell] += sim.faults.cell_drift_v
    return volts


class Bms16Simulator(SimDevice):
    """A BMS16 on a LiFePO4 pack; current_fn(now) -> A, positive = discharge."""

    TYPE = 'bms16'
    PERIOD = 0.25  # s: status, cells and the SMA frames all at 4 Hz, as the vendor states

    def __init__(self, name: str | None = None, base_id: int = 500, cells: int = 16,
                 current_fn: Callable[[float], float] | None = None,
                 capacity_ah: float = 100.0, send_sma: bool = True, seed: int = 0) -> None:
        super().__init__(name)
        self.codec = Bms16Codec(base_id)
        self.sma_codec = SmaCodec()
        self.cells = cells
        self.current_fn = current_fn or drive_current_a
        self.capacity_ah = capacity_ah
        self.send_sma = send_sma
        rng = random.Random(seed)
        self.cell_offsets_v = [rng.uniform(-0.008, 0.008) for _ in range(16)]
        self.soc_pct = 80.0
        self.current_a = 0.0  # wire sign: positive = discharge
        self.temperature_c = 25.0
        self.config1: Bms16ConfigPart1 | None = None
        self.config2: Bms16ConfigPart2 | None = None
        self.powered = True
        self.acknowledged = False
        self._periodic = Periodic(self.PERIOD)
        self._elapsed = Elapsed()

    # --- model --------------------------------------------------------------------
    def power_on(self) -> None:
        """Power the unit back on (after a 508 power-off)."""
        self.powered = True

    def cell_voltages(self) -> list[float]:
        """Present cell voltages (V) of the configured number of cells."""
        return [min(CELL_MAX_RAW / 100, max(0.0, v)) for v in pack_cells(self)]

    def error(self) -> Bms16Error:
        """Return the error reported: the injected one, else low SoC against its warning."""
        if self.faults.error_code is not None:
            return Bms16Error(self.faults.error_code)
        if self.config1 is not None and self.soc_pct < self.config1.soc_warning_pct:
            return Bms16Error.LOW_SOC
        return Bms16Error.NONE

    def _step(self, now: float) -> None:
        dt = self._elapsed(now)
        self.current_a = float(self.current_fn(now)) if self.powered else 0.0
        self.soc_pct = integrate_soc(self.soc_pct, self.current_a, dt, self.capacity_ah)
        self.temperature_c = thermal_lag(
            self.temperature_c, 25.0 + 0.08 * abs(self.current_a), dt)

    # --- bus side -----------------------------------------------------------------
    def tick(self, now: float) -> list[Frame]:
        """Advance the pack to ``now`` and return the frames due."""
        self._step(now)
        if not self._periodic.due(now) or not self.powered or self.faults.silent:
            return []
        frames = self._own_frames()
        sma = self._sma_frames() if self.send_sma else []
        if self.faults.malformed:
            return [self.corrupt(f) for f in frames] + [sma_empty(f) for f in sma]
        return frames + sma

    def _own_frames(self) -> list[Frame]:
        volts = self.cell_voltages() + [0.0] * (16 - self.cells)
        pack_v = sum(volts[:self.cells])
        status = Bms16Status(self.error(), round(self.soc_pct), round(pack_v, 1),
                             round(self.current_a, 1), round(self.temperature_c))
        frames = [self.codec.encode(status)]
        for first, count in zip(CELL_FRAME_FIRST, CELL_FRAME_COUNT):
            frames.append(self.codec.encode(
                Bms16Cells(first, tuple(volts[first:first + count]))))
        return frames

    def _sma_frames(self) -> list[Frame]:
        error = self.error()
        min_cell = self.config1.min_cell_v if self.config1 else 2.8
        full_v = (self.config1.full_voltage_v if self.config1
                  else round(self.cells * 3.55, 1))

        def flag(active: bool) -> SmaFlag:
            return SmaFlag.ACTIVE if active else SmaFlag.OK

        # The BMS16 reports these four conditions only (vendor: bytes 0 and 1 of 0x35A).
        alarms = SmaAlarms(alarms={
            'high_voltage': flag(error == Bms16Error.CHARGE_DISABLED_OVERVOLTAGE),
            'low_voltage': flag(error in (Bms16Error.LOAD_DISABLED_UNDERVOLTAGE,
                                          Bms16Error.CRITICAL_VOLTAGE)),
            'high_temperature': flag(error == Bms16Error.OVERTEMPERATURE),
            'high_discharge_current': flag(error == Bms16Error.OVERCURRENT_SHUTDOWN),
        })
        volts = self.cell_voltages()
        return [self.sma_codec.encode(m) for m in (
            SmaLimits(full_v, 1000.0, 1000.0, round(self.cells * min_cell, 1)),
            SmaSoc(round(self.soc_pct), 100, None),
            SmaBattery(round(sum(volts), 2), round(-self.current_a, 1),
                       round(self.temperature_c, 1)),
            alarms)]

    def _clamped_config(self, arbitration_id: int,
                        data: bytes) -> Bms16ConfigPart1 | Bms16ConfigPart2 | None:
        """Read a configuration frame with a value out of range as the unit does (to clamp)."""
        offset = arbitration_id - self.codec.base_id
        if offset == CONFIG_1 and len(data) == 8:
            part1: dict[str, Any] = SETTINGS.decode(0, data)  # no fail: unchecked
            return Bms16ConfigPart1(**part1)
        if offset == CONFIG_2 and len(data) == 4 and data[3] < len(SHUNT_SIZES_A):
            return Bms16ConfigPart2(**SETTINGS.decode(1, data))
        return None

    def on_frame(self, frame: Frame, now: float) -> None:
        """Take configuration and commands addressed to this unit (ignored while off)."""
        if not self.powered or frame.arbitration_id not in self.codec.arbitration_ids:
            return
        data = bytes(frame.data)
        try:
            message = self.codec.decode(frame.arbitration_id, data)
        except MalformedFrameError:
            # the real unit clamps a configuration value out of range; it ignores any other
            # frame it cannot read (a wrong length, an unknown shunt code)
            clamped = self._clamped_config(frame.arbitration_id, data)
            if clamped is None:
                return
            message = clamped
        except ProtocolError:
            return
        if isinstance(message, Bms16ConfigPart1):
            values: dict[str, Any] = {
                name: (int if name == 'cells' else float)(_clamped(name, value))
                for name, value in vars(message).items()}
            self.config1 = Bms16ConfigPart1(**values)
            self.cells = self.config1.cells
            self.capacity_ah = self.config1.pack_capacity_ah
        elif isinstance(message, Bms16ConfigPart2):
            self.config2 = Bms16ConfigPart2(
                _clamped('max_cell_v', message.max_cell_v),
                _clamped('hysteresis_v', message.hysteresis_v),
                _clamped('balance_v', message.balance_v), message.shunt_size_a)
        elif isinstance(message, AcknowledgeError):
            self.acknowledged = True
            self.faults.error_code = None
        elif isinstance(message, ResetSoc):
            self.soc_pct = 100.0
        elif isinstance(message, PowerOff):
            self.powered = False
