# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
SMA Sunny Island protocol BMS state: 0x351..0x35F and its dialects -> BatteryState, diagnostics.

Fixed IDs (no base_id). The primary frame is 0x356 (voltage, current, temperature); its
voltage in SMA's 0.01 V or the 0.1 V some senders use (``voltage_scale``, devices/
sma_voltage.py: unknown until the battery's 0x351 tells). SoC comes from 0x355 (the
high-resolution SoC only where it agrees with the integer one: real BMSs put zeros there),
capacity from 0x35F (0 = not sent: then Victron's installed capacity 0x379), and charge =
capacity x SoC while both are known and fresh (NaN otherwise); where the battery's evidence
says 0x35F is the charge left (it agrees with SoC x 0x379: devices/sma/capacity.py), the
charge is 0x35F and the capacity 0x379. The wire current is already
positive while charging, the ROS sign. "Not available" markers become NaN.

Commands: the only frame this device sends is the inverter keep-alive 0x305
(``inverter_keepalive``, devices/sma/keepalive.py), while commands are enabled.

Dialects (``protocols.sma_dialects``): Pylontech-style BMSs send their alarms in 0x359
instead of 0x35A; an active 0x359 alarm is ERROR and a warning WARN, exactly as in 0x35A,
and both feed the health. 0x35C (charge / discharge enable, charge requests), the module
counts (0x359, 0x372), the Victron name and cell ids, the energy counters (0x378), installed
capacity (0x379), product name (0x382) and the online status (0x35A byte 7) are diagnostics
values. Victron's 0x373 (min/max cell voltage and temperature) is shown in V and degC and
gives BatteryState.temperature (the hottest cell) when 0x356 carries none; so does the
binary 0x370 of Pylontech V2 / Seplos BMSs (their 0x371: the cells' ids).

Every frame (group) expires on its own: a value older than ``stale_timeout`` is unknown
again (NaN, left out of the diagnostics values and listed under 'frames expired'), so a BMS
that keeps sending 0x356 but stops sending 0x35A never shows old alarms as current. The
identity frames (0x35E, 0x35F, 0x370, 0x371) come slowly and keep for IDENTITY_TIMEOUT.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Hashable, Iterable, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, Device, DiagnosticReport, Level, NAN, PowerSupplyHealth, Sent)
from ams_can_bridge.devices.generated_configs import SmaConfig
from ams_can_bridge.devices.sma.capacity import capacity_values, InfoCapacity
from ams_can_bridge.devices.sma.keepalive import InverterKeepalive, KEEPALIVE_PERIOD
from ams_can_bridge.devices.sma.values import fmt, sma_values
from ams_can_bridge.devices.sma.voltage import AUTO, SCALE_CHOICES, ScaleInUse, VoltageScale
from ams_can_bridge.devices.timed import TimedStore
from ams_can_bridge.errors import ParamError
from ams_can_bridge.parameters import coerce, ParamSpec
from ams_can_bridge.devices.ports import Armed, InfoLog, SendFrame
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.sma import (
    ALARMS_ID, BATTERY_ID, INFO_ID, LIMITS_ID, MANUFACTURER_ID, SmaAlarms, SmaBattery,
    SmaBatteryInfo, SmaCodec, SmaLimits, SmaManufacturer, SmaSoc, SOC_ID)
from ams_can_bridge.protocols.sma_dialects import (
    CELL_ID_KINDS, PYLONTECH_ALARMS_ID, PYLONTECH_REQUEST_ID,
    PylontechAlarms, PylontechCellExtremes, PylontechCellIds, PylontechRequest,
    VICTRON_BMS_NAME1_ID, VICTRON_CELL_EXTREMES_ID,
    VICTRON_ENERGY_ID, VICTRON_INSTALLED_CAPACITY_ID, VICTRON_MIN_VOLTAGE_CELL_ID,
    VICTRON_MODULES_ID, VICTRON_PRODUCT_NAME_ID, VictronBmsName, VictronCellExtremes,
    VictronCellId, VictronEnergy, VictronInstalledCapacity, VictronModules, VictronProductName,
    keepalive_frame)
from ams_can_bridge.protocols.sma_scale import raw_voltage, scaled_voltage

# Alarm -> BatteryState health, first match wins (the most specific health first).
ALARM_HEALTH = (
    ('high_voltage', PowerSupplyHealth.OVERVOLTAGE),
    ('low_voltage', PowerSupplyHealth.DEAD),
    ('high_temperature', PowerSupplyHealth.OVERHEAT),
    ('high_temperature_charge', PowerSupplyHealth.OVERHEAT),
    ('low_temperature', PowerSupplyHealth.COLD),
    ('low_temperature_charge', PowerSupplyHealth.COLD),
)
# s: names and battery info are sent every few seconds, often less often than the rest.
IDENTITY_TIMEOUT = 30.0

# group key -> CAN ID (a group is one frame; the Victron texts share a type, so the key
# adds the part / kind).
GROUP_IDS: dict[Hashable, int] = {
    SmaLimits: LIMITS_ID, SmaSoc: SOC_ID, SmaBattery: BATTERY_ID, SmaAlarms: ALARMS_ID,
    SmaManufacturer: MANUFACTURER_ID, SmaBatteryInfo: INFO_ID,
    PylontechAlarms: PYLONTECH_ALARMS_ID, PylontechRequest: PYLONTECH_REQUEST_ID,
    (VictronBmsName, 1): VICTRON_BMS_NAME1_ID, (VictronBmsName, 2): VICTRON_BMS_NAME1_ID + 1,
    PylontechCellExtremes: VICTRON_BMS_NAME1_ID, PylontechCellIds: VICTRON_BMS_NAME1_ID + 1,
    VictronModules: VICTRON_MODULES_ID, VictronCellExtremes: VICTRON_CELL_EXTREMES_ID,
    **{(VictronCellId, kind): VICTRON_MIN_VOLTAGE_CELL_ID + k
       for k, kind in enumerate(CELL_ID_KINDS)},
    VictronEnergy: VICTRON_ENERGY_ID, VictronInstalledCapacity: VICTRON_INSTALLED_CAPACITY_ID,
    VictronProductName: VICTRON_PRODUCT_NAME_ID,
}
IDENTITY_GROUPS = frozenset({SmaManufacturer, SmaBatteryInfo, (VictronBmsName, 1),
                             (VictronBmsName, 2), VictronEnergy, VictronInstalledCapacity,
                             VictronProductName})
# What tells the 0x356 voltage scale (devices/sma/voltage.py)
EVIDENCE = (SmaBattery, SmaLimits, VictronCellExtremes, PylontechCellExtremes)
ALARM_GROUPS = (SmaAlarms, PylontechAlarms)


def group_key(reading: Any) -> Hashable:
    """Return the key a reading is kept under: its type, with the part for Victron texts."""
    if isinstance(reading, VictronBmsName):
        return (VictronBmsName, reading.part)
    if isinstance(reading, VictronCellId):
        return (VictronCellId, reading.kind)
    # a class is hashable; mypy checks type[...] against Hashable's __hash__ too strictly
    return type(reading)  # type: ignore[return-value]


def _nan(value: float | int | None) -> float:
    return NAN if value is None else float(value)


VOLTAGE_SCALE = ParamSpec(
    'voltage_scale', str, AUTO,
    "V per bit of 0x356's voltage: auto = from the battery's own 0x351 limits and cell "
    "voltages (unknown until 0x351 came; SMA's 0.01 with a WARN if they never tell), or 0.01 "
    '(SMA) / 0.1 (e.g. Discover Lynx II, Orion BMS 2)', choices=SCALE_CHOICES)


class SmaDevice(Device[SmaConfig]):
    """One BMS speaking the SMA Sunny Island protocol or its Pylontech / Victron dialects."""

    TYPE = 'sma'
    Config = SmaConfig
    codec: SmaCodec
    # Typical SMA-protocol BMSs send every 1 s (the BMS16 at 4 Hz): the default stale
    # timeout of 5 periods (5 s) must not flap on a 1 Hz sender.
    BROADCAST_PERIOD = 1.0
    DEFAULT_BASE_ID = None
    PARAMS = [VOLTAGE_SCALE]
    COMMAND_PARAMS = [
        ParamSpec('inverter_keepalive', bool, False,
                  'send the inverter keep-alive 0x305 (8 zero bytes) every '
                  f'{KEEPALIVE_PERIOD:g} s while commands_enabled, for BMSs that wait for an '
                  'inverter (Pylontech protocol); false = never', read_only=False),
    ]

    def __init__(self, name: str, config: SmaConfig | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, config, clock)
        self.codec = SmaCodec()
        self.readings: TimedStore[Hashable, Any] = TimedStore()  # by group_key: its type
        self.battery_stamp = NAN
        self.keepalive: InverterKeepalive | None = None  # made by attach_senders()
        self.scale = VoltageScale(f'{name}.voltage_scale', self._scale_setting(self.config),
                                  self.stale_timeout)
        self.info_capacity = InfoCapacity()  # what 0x35F's Ah is, from the evidence

    # --- commands ------------------------------------------------------------------------
    def keepalive_frame(self) -> Frame:
        """Build the inverter keep-alive 0x305 the bridge sends in the inverter's place."""
        return keepalive_frame()

    def sent_ids(self, config: SmaConfig | None = None) -> dict[tuple[int, bool], Sent]:
        """Return the keep-alive's ID while inverter_keepalive is true, else nothing."""
        if not (config or self.config).inverter_keepalive:
            return {}
        frame = self.keepalive_frame()
        return {(frame.arbitration_id, frame.is_extended_id): Sent('inverter keep-alive', True)}

    def attach_senders(self, send: SendFrame, log: InfoLog) -> list[Armed]:
        """Make the (disarmed) inverter keep-alive; armed while commands are enabled."""
        return [self.attach_keepalive(send, log.info)]

    def attach_keepalive(self, send: SendFrame,
                         log: Callable[[str], object],
                         period: float = KEEPALIVE_PERIOD) -> InverterKeepalive:
        """
        Make this device's (disarmed) keep-alive sending through ``send``.

        It follows ``inverter_keepalive`` on every configure(); the caller arms it while
        commands are enabled.
        """
        self.keepalive = InverterKeepalive(self.keepalive_frame, send, log, self.name, period)
        self.keepalive.set_enabled(bool(self.config.inverter_keepalive))
        return self.keepalive

    def configure(self, changes: Mapping[str, Any]) -> SmaConfig:
        """Apply parameter changes; the keep-alive follows inverter_keepalive at once."""
        new = super().configure(changes)
        if self.keepalive is not None:  # outside the device lock: stopping joins a thread
            self.keepalive.set_enabled(bool(new.inverter_keepalive))
        return new

    def config_problems(self, config: SmaConfig,
                        keys: Iterable[str] | None = None) -> list[str]:
        """Name a voltage_scale that is none of its choices (0.1 as a number is one)."""
        try:
            self._scale_setting(config)
        except ParamError as exc:
            return [str(exc)]
        return []

    def _scale_setting(self, config: SmaConfig) -> str:
        return coerce(f'{self.name}.voltage_scale', VOLTAGE_SCALE,
                      config.voltage_scale) or AUTO

    def _reconfigured(self, old: SmaConfig, new: SmaConfig) -> None:
        if (old.voltage_scale, old.stale_timeout) != (new.voltage_scale, new.stale_timeout):
            self.scale.reset(self._scale_setting(new), self.stale_timeout)
        self.info_capacity.reset()

    def _handle(self, reading: Any, stamp: float) -> bool:
        key = group_key(reading)
        now = self.clock()
        self.readings.put(key, reading, now)
        if isinstance(reading, EVIDENCE) and self.scale.undecided:
            if isinstance(reading, SmaBattery):
                self.scale.saw_battery(now)
            self._scale(self._fresh()[0])  # decide now: 0x351 may stop before a report
        if isinstance(reading, SmaBattery):
            self.battery_stamp = stamp
            return True
        return False

    def _scale(self, readings: Mapping[Hashable, Any]) -> tuple[ScaleInUse, float | None]:
        """Return the 0x356 voltage scale in use and the voltage read with it (lock held)."""
        battery = readings.get(SmaBattery)
        raw = None if battery is None else raw_voltage(battery)
        cells = readings.get(VictronCellExtremes) or readings.get(PylontechCellExtremes)
        cells_v = None
        if cells is not None and None not in (cells.min_cell_v, cells.max_cell_v):
            cells_v = (cells.min_cell_v, cells.max_cell_v)
        in_use = self.scale.in_use(raw, readings.get(SmaLimits), cells_v, self.clock())
        return in_use, scaled_voltage(raw, in_use.scale)

    def group_timeout(self, key: Hashable) -> float:
        """Seconds a group's values stay valid after its frame."""
        if key in IDENTITY_GROUPS:
            return max(self.stale_timeout, IDENTITY_TIMEOUT)
        return self.stale_timeout

    def _fresh(self) -> tuple[dict[Hashable, Any], dict[Hashable, float]]:
        """Split the readings (lock held): (fresh ones, {expired key: seconds silent})."""
        return self.readings.split(self.clock(), self.group_timeout)

    def _battery_report(self) -> BatteryReport:
        readings, _ = self._fresh()
        report = BatteryReport()
        soc = readings.get(SmaSoc)
        if soc is not None:
            report.percentage = _nan(soc.percent) / 100
        capacity, charge, _ = self.info_capacity.read(readings)
        if capacity is not None:
            report.capacity = report.design_capacity = capacity
            # Remaining Ah only where both are known and fresh: NaN times anything is NaN.
            report.charge = report.capacity * report.percentage
        if charge is not None:  # 0x35F is the charge left (devices/sma/capacity.py)
            report.charge = charge
        if any(k in readings for k in ALARM_GROUPS):
            report.power_supply_health = self._health(readings)
        battery = readings.get(SmaBattery)
        if battery is None:
            return report
        report.stamp = self.battery_stamp
        report.voltage = _nan(self._scale(readings)[1])
        report.current = _nan(battery.current_a)
        report.temperature = _nan(battery.temperature_c)
        cells = readings.get(VictronCellExtremes) or readings.get(PylontechCellExtremes)
        if math.isnan(report.temperature) and cells is not None:
            report.temperature = _nan(cells.max_temperature_c)  # the hottest cell
        report.power_supply_status = current_status(report.current)
        report.present = True
        return report

    @staticmethod
    def _active(readings: Mapping[Hashable, Any]) -> tuple[list[str], list[str]]:
        """Active alarm and warning names of 0x35A and 0x359 together, without repeats."""
        alarms: list[str] = []
        warnings: list[str] = []
        for key in ALARM_GROUPS:
            flags = readings.get(key)
            if flags is not None:
                alarms += [n for n in flags.active_alarms if n not in alarms]
                warnings += [n for n in flags.active_warnings if n not in warnings]
        return alarms, warnings

    def _health(self, readings: Mapping[Hashable, Any]) -> PowerSupplyHealth:
        active, _ = self._active(readings)
        for name, health in ALARM_HEALTH:
            if name in active:
                return health
        return PowerSupplyHealth.UNSPEC_FAILURE if active else PowerSupplyHealth.GOOD

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        readings, expired = self._fresh()
        values = sma_values(readings) if with_values else {}
        if with_values and self.keepalive is not None:
            values['inverter keep-alive (0x305)'] = self.keepalive.describe()
        if expired and with_values:
            values['frames expired'] = ', '.join(
                f'0x{GROUP_IDS[k]:X} ({s:.1f} s ago)' for k, s in sorted(
                    expired.items(), key=lambda item: GROUP_IDS[item[0]]))
        if with_values and readings.get(SmaBatteryInfo) is not None:
            values.update(capacity_values(self.info_capacity, readings))
        level = Level.OK
        parts: list[str] = []
        in_use, voltage = self._scale(readings)
        battery = readings.get(SmaBattery)
        if with_values and battery is not None and battery.voltage_v is not None:
            values['voltage V'] = 'unknown' if in_use.scale is None else fmt(voltage)
            values['voltage scale (0x356)'] = in_use.text
        alarms, warnings = self._active(readings)
        if alarms:
            level = Level.ERROR
            parts.append('alarms ' + ', '.join(alarms))
        if warnings:
            level = max(level, Level.WARN)
            parts.append('warnings ' + ', '.join(warnings))
        if not any(k in readings for k in ALARM_GROUPS):
            gone = [k for k in ALARM_GROUPS if k in expired]
            if gone:
                level = max(level, Level.WARN)
                parts.append(f'alarm frame 0x{GROUP_IDS[gone[0]]:X} silent for '
                             f'{expired[gone[0]]:.1f} s: alarms unknown')
            else:
                parts.append('no alarm frame (0x35A or 0x359) yet')
        if in_use.warning:
            level = max(level, Level.WARN)
            parts.append(in_use.warning)
        elif level == Level.OK and not parts:
            parts.append('OK')
        soc = readings.get(SmaSoc)
        if battery is not None:
            shown = 'voltage unknown' if in_use.scale is None else fmt(voltage, 'V')
            summary = f'{shown}, {fmt(battery.current_a, "A")}'
            if soc is not None:
                summary = f'SoC {fmt(soc.soc_pct, "%")}, ' + summary
            parts.append(summary)
        return DiagnosticReport(level, '; '.join(parts), values)
