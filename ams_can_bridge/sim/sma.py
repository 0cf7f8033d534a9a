# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Simulated BMS speaking the SMA Sunny Island protocol (a 16-cell LiFePO4 48 V pack).

Periods: 0x351, 0x355, 0x356, 0x35A every 1 s, the rate common SMA-protocol BMSs send at
(chargers such as the Wakespeed WS500 require 0x351/0x356 at least every 1000 ms, the Sunny
Island stops after 3 s without 0x351); 0x35E and 0x35F every 5 s. On the wire the current
is positive while CHARGING (the profile's discharge-positive current is negated).

Dialects (``dialect``, the simulator's ``--sma-dialect``): ``sma`` sends the frames above;
``pylontech`` sends 0x359 (alarms, warnings, module count) and 0x35C (charge / discharge
enable, charge request) instead of 0x35A, as Pylontech-family BMSs do; ``victron`` adds to
the SMA frames the BMS name (0x370/0x371, with the info frames), the module counts (0x372),
the min/max cell voltage and temperature (0x373) and their cell ids (0x374..0x377), every 1 s.

0x355 layout (``soc_layout``, the simulator's ``--sma-soc-frame``): ``sma`` (SoC, SoH,
high-resolution SoC; 6 bytes), ``byd`` (SoC, SoH and four zero bytes, as a BYD LVS sends
it) or ``diybms`` (the SoC alone, DLC 2, as diyBMS sends it): ``protocols.sma.SOC_LAYOUTS``.

``voltage_scale`` (``--sma-voltage-scale``): 0x356's voltage in SMA's 0.01 V or in 0.1 V as
a Discover Lynx II and an Orion BMS 2 send it. ``send_capacity=False``
(``--sma-no-capacity``): 0x35F carries capacity 0 (not sent), as Revov/BYD and Eco-Worthy
batteries do; the victron dialect still sends the installed capacity in 0x379.

Faults: ``silent``; ``malformed`` (frames without data: malformed for every SMA ID, where a
dropped byte may still be a valid DLC); ``extra['alarm']`` / ``extra['warning']``: a
condition name or a list of them (``protocols.sma.SMA_CONDITIONS``) reported ACTIVE;
``cell_drift_v``: the pack has no cell frames here, so a drift of 50 mV or more shows as the
``cell_imbalance`` warning (0x35A; the Pylontech 0x359 has no bit for it, nor for the other
conditions outside ``PYLONTECH_CONDITION_NAMES``: those are not sent in that dialect).
``error_code`` has no meaning in this protocol and is ignored.
"""
from __future__ import annotations

import random
from typing import Any, Callable

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.sma import (
    SMA_CONDITIONS, SmaAlarms, SmaBattery, SmaBatteryInfo, SmaCodec, SmaFlag, SmaLimits,
    SOC_LAYOUTS,
    SmaManufacturer, SmaReading, SmaSoc)
from ams_can_bridge.protocols.sma_dialects import (
    CELL_ID_KINDS, KELVIN_OFFSET, PYLONTECH_CONDITION_NAMES, PylontechAlarms, PylontechRequest,
    VictronBmsName, VictronCellExtremes, VictronCellId, VictronInstalledCapacity, VictronModules)
from ams_can_bridge.protocols.sma_scale import VOLTAGE_SCALES
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge.sim.bms16 import CELL_RESISTANCE_OHM, lfp_cell_ocv, sma_empty
from ams_can_bridge.sim.pack import Elapsed, integrate_soc, thermal_lag
from ams_can_bridge.sim.profiles import drive_current_a

CELLS = 16
# Conditions this BMS reports (the others are sent as NOT_SUPPORTED, as real BMSs do).
SUPPORTED = ('general', 'high_voltage', 'low_voltage', 'high_temperature', 'low_temperature',
             'high_discharge_current', 'high_charge_current', 'bms_internal',
             'cell_imbalance')
IMBALANCE_WARNING_V = 0.05
DIALECTS = ('sma', 'pylontech', 'victron')
MODULES = 1  # one 16-cell module
CELL_SPREAD_V = 0.004  # each cell's offset from the pack mean, at most
FULL_PCT = 99.5  # charge enable goes off above this SoC (0x35C)
EMPTY_PCT = 5.0  # discharge enable goes off below it, and the BMS asks for charge


def _names(value: Any) -> set[str]:
    if not value:
        return set()
    names = {value} if isinstance(value, str) else set(value)
    unknown = names - set(SMA_CONDITIONS)
    if unknown:
        raise ConfigError(f'unknown SMA condition(s) {sorted(unknown)}: use '
                          + ', '.join(SMA_CONDITIONS))
    return names


class SmaSimulator(SimDevice):
    """An SMA-protocol BMS; current_fn(now) -> A, positive = discharge."""

    TYPE = 'sma'
    PERIOD = 1.0
    INFO_PERIOD = 5.0

    def __init__(self, name: str | None = None,
                 current_fn: Callable[[float], float] | None = None,
                 capacity_ah: float = 100.0, manufacturer: str = 'SIMBMS',
                 seed: int = 0, dialect: str = 'sma', bms_name: str = 'SIMBMS 16S LFP',
                 soc_layout: str = 'sma', voltage_scale: float = 0.01,
                 send_capacity: bool = True) -> None:
        super().__init__(name)
        if voltage_scale not in VOLTAGE_SCALES:
            raise ConfigError(f'SMA 0x356 voltage scale {voltage_scale!r}: use one of '
                              + ', '.join(f'{s:g}' for s in VOLTAGE_SCALES))
        self.voltage_scale = voltage_scale
        self.send_capacity = send_capacity
        if dialect not in DIALECTS:
            raise ConfigError(f'SMA dialect {dialect!r}: use one of ' + ', '.join(DIALECTS))
        if soc_layout not in SOC_LAYOUTS:
            raise ConfigError(f'SMA 0x355 layout {soc_layout!r}: use one of '
                              + ', '.join(SOC_LAYOUTS))
        self.soc_layout = soc_layout
        if not 1 <= len(bms_name) <= 16:
            raise ConfigError(f'bms_name {bms_name!r}: 1..16 ASCII characters (0x370 + 0x371)')
        self.dialect = dialect
        self.bms_name = bms_name
        rng = random.Random(seed)
        self.cell_offsets_v = [rng.uniform(-CELL_SPREAD_V, CELL_SPREAD_V) for _ in range(CELLS)]
        self.codec = SmaCodec()
        self.current_fn = current_fn or drive_current_a
        self.capacity_ah = capacity_ah
        self.manufacturer = manufacturer
        self.seed = seed
        self.soh_pct = 100 - seed % 5  # a fleet of simulated packs ages differently
        self.soc_pct = 80.0
        self.current_a = 0.0  # profile sign: positive = discharge
        self.temperature_c = 25.0
        self._periodic = Periodic(self.PERIOD)
        self._info = Periodic(self.INFO_PERIOD)
        self._elapsed = Elapsed()

    def voltage_v(self) -> float:
        """Pack terminal voltage."""
        return CELLS * (lfp_cell_ocv(self.soc_pct) - self.current_a * CELL_RESISTANCE_OHM)

    def cell_voltages(self) -> list[float]:
        """Each cell's terminal voltage (the drift fault on cell faults.drift_cell)."""
        mean = self.voltage_v() / CELLS
        cells = [mean + offset for offset in self.cell_offsets_v]
        cells[self.faults.drift_cell % CELLS] += self.faults.cell_drift_v
        return cells

    def alarms(self) -> SmaAlarms:
        """Alarm / warning flags now: injected ones ACTIVE, other supported ones OK."""
        alarm = _names(self.faults.extra.get('alarm'))
        warning = _names(self.faults.extra.get('warning'))
        if abs(self.faults.cell_drift_v) >= IMBALANCE_WARNING_V:
            warning.add('cell_imbalance')

        def flags(active: set[str]) -> dict[str, SmaFlag]:
            result = {n: SmaFlag.OK for n in SUPPORTED}
            result.update({n: SmaFlag.ACTIVE for n in active})
            return result
        return SmaAlarms(flags(alarm), flags(warning))

    def pylontech_alarms(self) -> PylontechAlarms:
        """0x359 now: the injected conditions 0x359 has a bit for."""
        flags = self.alarms()
        return PylontechAlarms(
            frozenset(flags.active_alarms) & set(PYLONTECH_CONDITION_NAMES),
            frozenset(flags.active_warnings) & set(PYLONTECH_CONDITION_NAMES), MODULES)

    def pylontech_request(self) -> PylontechRequest:
        """0x35C now: no charge when full or over-voltage, no discharge when empty."""
        active = set(self.alarms().active_alarms)
        return PylontechRequest(
            self.soc_pct < FULL_PCT and 'high_voltage' not in active,
            self.soc_pct > EMPTY_PCT and 'low_voltage' not in active,
            self.soc_pct <= EMPTY_PCT)

    def victron_messages(self) -> list[SmaReading]:
        """0x372..0x377 now: module counts, min/max cell voltage and temperature, cell ids."""
        cells = self.cell_voltages()
        low, high = cells.index(min(cells)), cells.index(max(cells))
        # The module's two sensors read 1 degC either side of the pack temperature.
        t_low = round(self.temperature_c - 1.0 + KELVIN_OFFSET)
        t_high = round(self.temperature_c + 1.0 + KELVIN_OFFSET)
        blocking_charge = MODULES if not self.pylontech_request().charge_enable else 0
        return [
            VictronModules(MODULES, blocking_charge, 0, 0),
            VictronCellExtremes(round(cells[low], 3), round(cells[high], 3), t_low, t_high),
            VictronCellId(CELL_ID_KINDS[0], f'C{low + 1}'),
            VictronCellId(CELL_ID_KINDS[1], f'C{high + 1}'),
            VictronCellId(CELL_ID_KINDS[2], 'T1'),
            VictronCellId(CELL_ID_KINDS[3], 'T2'),
        ]

    def _step(self, now: float) -> None:
        dt = self._elapsed(now)
        self.current_a = float(self.current_fn(now))
        self.soc_pct = integrate_soc(self.soc_pct, self.current_a, dt, self.capacity_ah)
        self.temperature_c = thermal_lag(
            self.temperature_c, 25.0 + 0.08 * abs(self.current_a), dt)

    def _wire_voltage(self) -> float:
        """0x356's voltage as SmaBattery carries it (0.01 V/bit): a 0.1 V sender's count."""
        steps = round(self.voltage_v() / self.voltage_scale)
        return steps / 100  # the raw count at SMA's 0.01 V, what the wire carries

    def tick(self, now: float) -> list[Frame]:
        """Advance the pack to ``now`` and return the frames due."""
        self._step(now)
        messages: list[SmaReading] = []
        if self._periodic.due(now):
            messages += [
                SmaLimits(CELLS * 3.45, round(0.5 * self.capacity_ah, 1),
                          round(1.0 * self.capacity_ah, 1), CELLS * 3.0),
                SmaSoc(round(self.soc_pct), self.soh_pct, round(self.soc_pct, 2)),
                SmaBattery(self._wire_voltage(), round(-self.current_a, 1),
                           round(self.temperature_c, 1)),
            ]
            if self.dialect == 'pylontech':
                messages += [self.pylontech_alarms(), self.pylontech_request()]
            else:
                messages.append(self.alarms())
            if self.dialect == 'victron':
                messages += self.victron_messages()
        if self._info.due(now):
            capacity = round(self.capacity_ah)
            # BMS version 1.0: byte 2 major, byte 3 minor (doc/protocols.md 5.2), U16 0x0001
            messages += [SmaManufacturer(self.manufacturer),
                         SmaBatteryInfo(1, 0x0001, capacity if self.send_capacity else 0)]
            if self.dialect == 'victron':
                messages += [VictronBmsName(1, self.bms_name[:8]),
                             VictronInstalledCapacity(capacity)]
                if len(self.bms_name) > 8:
                    messages.append(VictronBmsName(2, self.bms_name[8:]))
        if self.faults.silent or not messages:
            return []
        frames = [self.codec.encode_soc(m, self.soc_layout) if isinstance(m, SmaSoc)
                  else self.codec.encode(m) for m in messages]
        if self.faults.malformed:
            return [sma_empty(f) for f in frames]
        return frames
