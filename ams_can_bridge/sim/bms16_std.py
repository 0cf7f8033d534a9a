# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Simulated ZEVA BMS16 in its standard form (EVMS3 protocol, 29-bit IDs): ``--bms16-variant``.

The LiFePO4 pack of ``sim.bms16`` on the frames of doc/protocols.md section 6: ID 30 with
byte 5 = 255 (4 Hz), cells as BMS12 modules 0 and 1 (301, 302, 311, 312), the shunt current on
ID 40. It stores IDs 32..35 once all four have come (35 last, as the EVMS3 saves on it),
clears the error on 37, sets the SoC to 100 % on 38 and powers off on 39 (silent until
``power_on()``). How the real unit clamps or rejects a bad setting is not published: a set
with a raw value outside the Monitor's ranges is ignored here.
"""
from __future__ import annotations

import random
from typing import Any, Callable

from ams_can_bridge.protocols.bms16_std import (
    Bms16StdCodec, Bms16StdStatus, CELL_FRAMES, CELLS_PER_MODULE, CONFIG1, decode_config,
    DEFAULT_BASE_ID)
from ams_can_bridge.protocols.common import CELL_V_MAX, Frame
from ams_can_bridge.protocols.evms3 import (
    ACK_ERROR, BatteryCurrent, Bms12Cells, Evms3Error, Evms3State, POWER_OFF, RESET_SOC)
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge.sim.bms16 import pack_cells
from ams_can_bridge.sim.pack import Elapsed, four, integrate_soc, thermal_lag
from ams_can_bridge.sim.profiles import drive_current_a


class Bms16StdSimulator(SimDevice):
    """A standard-form BMS16 on a LiFePO4 pack; current_fn(now) -> A, positive = discharge."""

    TYPE = 'bms16'
    PERIOD = 0.25

    def __init__(self, name: str | None = None, base_id: int = DEFAULT_BASE_ID,
                 cells: int = 16, current_fn: Callable[[float], float] | None = None,
                 capacity_ah: float = 100.0, shunt: bool = True, seed: int = 0) -> None:
        super().__init__(name)
        self.codec = Bms16StdCodec(base_id)
        self.cells = cells
        self.current_fn = current_fn or drive_current_a
        self.capacity_ah = capacity_ah
        self.shunt = shunt  # without a shunt the BMS16 sends no current (no ID 40)
        rng = random.Random(seed)
        self.cell_offsets_v = [rng.uniform(-0.008, 0.008) for _ in range(16)]
        self.soc_pct = 80.0
        self.current_a = 0.0
        self.temperature_c = 25.0
        self.config: dict[str, Any] | None = None
        self._config_parts: dict[int, bytes] = {}
        self.powered = True
        self.acknowledged: Evms3Error | None = None
        self._periodic = Periodic(self.PERIOD)
        self._elapsed = Elapsed()

    def power_on(self) -> None:
        """Power the unit back on (after an ID 39 power-off)."""
        self.powered = True

    def cell_voltages(self) -> list[float]:
        """Present cell voltages (V) of the configured number of cells."""
        return [round(min(CELL_V_MAX, max(0.0, v)), 3) for v in pack_cells(self)]

    def error(self) -> Evms3Error:
        """Return the error reported: the injected one, else low SoC against its warning."""
        if self.faults.error_code is not None:
            return Evms3Error(self.faults.error_code)
        if self.config is not None and self.soc_pct < self.config['soc_warning_pct']:
            return Evms3Error.LOW_SOC_WARNING
        return Evms3Error.NONE

    def tick(self, now: float) -> list[Frame]:
        """Advance the pack to ``now`` and return the frames due."""
        dt = self._elapsed(now)
        self.current_a = float(self.current_fn(now)) if self.powered else 0.0
        self.soc_pct = integrate_soc(self.soc_pct, self.current_a, dt, self.capacity_ah)
        self.temperature_c = thermal_lag(
            self.temperature_c, 25.0 + 0.08 * abs(self.current_a), dt)
        if not self._periodic.due(now) or not self.powered or self.faults.silent:
            return []
        frames = self._frames()
        return [self.corrupt(f) for f in frames] if self.faults.malformed else frames

    def _frames(self) -> list[Frame]:
        volts = self.cell_voltages() + [0.0] * (16 - self.cells)
        state = Evms3State.CHARGING if self.current_a < -0.5 else Evms3State.RUNNING
        status = Bms16StdStatus(state, self.error(),
                                round(self.soc_pct * self.capacity_ah / 100, 1),
                                round(sum(volts[:self.cells]), 1),
                                round(self.temperature_c))
        frames = [self.codec.encode(status)]
        for (module, reply), first in CELL_FRAMES.items():
            if first < self.cells:  # module 1 sends only when cells 9.. exist
                frames.append(self.codec.encode(Bms12Cells(
                    module, 4 * (reply - 1), four(volts[first:first + 4]))))
        if self.shunt:
            frames.append(self.codec.encode(BatteryCurrent(round(self.current_a, 3))))
        return frames

    def on_frame(self, frame: Frame, now: float) -> None:
        """Take settings and commands addressed to this unit (ignored while off)."""
        if not self.powered or not frame.is_extended_id:
            return
        offset = frame.arbitration_id - self.codec.base_id
        data = bytes(frame.data)
        if CONFIG1 <= offset < CONFIG1 + 4 and len(data) == 8:
            self._config_parts[offset - CONFIG1] = data
            if offset == CONFIG1 + 3 and len(self._config_parts) == 4:
                self._store([self._config_parts[k] for k in range(4)])
        elif offset == ACK_ERROR and len(data) == 1:
            self.acknowledged = Evms3Error(data[0]) if data[0] <= 16 else None
            if data[0] == int(self.error()):
                self.faults.error_code = None
        elif offset == RESET_SOC and not data:
            self.soc_pct = 100.0
        elif offset == POWER_OFF and not data:
            self.powered = False

    def _store(self, payloads: list[bytes]) -> None:
        self._config_parts.clear()
        try:
            values = decode_config(payloads)
        except ValueError:
            return
        self.config = values
        self.cells = max(CELLS_PER_MODULE, values['cells'])
        self.capacity_ah = float(values['pack_capacity_ah'])
