"""
SMA Sunny Island protocol BMS state: 0x351..0x35F -> BatteryState, diagnostics.

Fixed IDs (no base_id). The primary frame is 0x356 (voltage, current, temperature); SoC comes
from 0x355 (the high-resolution SoC when the BMS sends one), capacity from 0x35F. The wire
current is already positive while charging, the ROS sign. "Not available" markers become NaN.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, Device, DiagnosticReport, Level, NAN, ParamSpec,
    PowerSupplyHealth)
from ams_can_bridge.protocols.sma import (
    SmaAlarms, SmaBattery, SmaBatteryInfo, SmaCodec, SmaLimits, SmaManufacturer, SmaReading,
    SmaSoc)

# Alarm -> BatteryState health, first match wins (the most specific health first).
ALARM_HEALTH = (
    ('high_voltage', PowerSupplyHealth.OVERVOLTAGE),
    ('low_voltage', PowerSupplyHealth.DEAD),
    ('high_temperature', PowerSupplyHealth.OVERHEAT),
    ('high_temperature_charge', PowerSupplyHealth.OVERHEAT),
    ('low_temperature', PowerSupplyHealth.COLD),
    ('low_temperature_charge', PowerSupplyHealth.COLD),
)


def _fmt(value: float | int | None, unit: str = '') -> str:
    if value is None:
        return 'not available'
    return f'{value:g}' + (f' {unit}' if unit else '')


def _nan(value: float | int | None) -> float:
    return NAN if value is None else float(value)


def sma_values(readings: Mapping[type, SmaReading], prefix: str = '') -> dict[str, str]:
    """Diagnostic values of every SMA message received so far (keyed by reading type)."""
    values: dict[str, str] = {}
    limits = readings.get(SmaLimits)
    if limits is not None:
        values[prefix + 'charge voltage limit V'] = _fmt(limits.charge_voltage_v)
        values[prefix + 'charge current limit A'] = _fmt(limits.charge_current_a)
        values[prefix + 'discharge current limit A'] = _fmt(limits.discharge_current_a)
        values[prefix + 'discharge voltage limit V'] = _fmt(limits.discharge_voltage_v)
    soc = readings.get(SmaSoc)
    if soc is not None:
        values[prefix + 'soc %'] = _fmt(soc.soc_pct)
        values[prefix + 'soh %'] = _fmt(soc.soh_pct)
        values[prefix + 'soc high resolution %'] = _fmt(soc.soc_hires_pct)
    battery = readings.get(SmaBattery)
    if battery is not None:
        values[prefix + 'voltage V'] = _fmt(battery.voltage_v)
        values[prefix + 'current A (positive = charging)'] = _fmt(battery.current_a)
        values[prefix + 'temperature degC'] = _fmt(battery.temperature_c)
    alarms = readings.get(SmaAlarms)
    if alarms is not None:
        values[prefix + 'alarms active'] = ', '.join(alarms.active_alarms) or 'none'
        values[prefix + 'warnings active'] = ', '.join(alarms.active_warnings) or 'none'
        for name, flag in alarms.alarms.items():
            values[f'{prefix}alarm {name}'] = flag.name
        for name, flag in alarms.warnings.items():
            values[f'{prefix}warning {name}'] = flag.name
    maker = readings.get(SmaManufacturer)
    if maker is not None:
        values[prefix + 'manufacturer'] = maker.name
    info = readings.get(SmaBatteryInfo)
    if info is not None:
        values[prefix + 'battery type'] = _fmt(info.battery_type)
        values[prefix + 'bms version'] = _fmt(info.bms_version)
        values[prefix + 'capacity Ah'] = _fmt(info.capacity_ah)
    return values


class SmaDevice(Device):
    """One BMS speaking the SMA Sunny Island protocol (fixed IDs 0x351..0x35F)."""

    TYPE = 'sma'
    # Typical SMA-protocol BMSs send every 1 s (the BMS16 at 4 Hz): the default stale
    # timeout of 5 periods (5 s) must not flap on a 1 Hz sender.
    BROADCAST_PERIOD = 1.0
    DEFAULT_BASE_ID = None
    PARAMS: list[ParamSpec] = []

    def __init__(self, name: str, params: Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, params, clock)
        self.codec = SmaCodec()
        self.readings: dict[type, SmaReading] = {}
        self.battery_stamp = NAN

    def _handle(self, reading: Any, stamp: float) -> bool:
        self.readings[type(reading)] = reading
        if isinstance(reading, SmaBattery):
            self.battery_stamp = stamp
            return True
        return False

    def _battery_report(self) -> BatteryReport:
        report = BatteryReport()
        soc = self.readings.get(SmaSoc)
        if soc is not None:
            pct = soc.soc_hires_pct if soc.soc_hires_pct is not None else soc.soc_pct
            report.percentage = _nan(pct) / 100
        info = self.readings.get(SmaBatteryInfo)
        if info is not None:
            report.capacity = report.design_capacity = _nan(info.capacity_ah)
            if not math.isnan(report.capacity):
                report.charge = report.capacity * report.percentage
        alarms = self.readings.get(SmaAlarms)
        if alarms is not None:
            report.power_supply_health = self._health(alarms)
        battery = self.readings.get(SmaBattery)
        if battery is None:
            return report
        report.stamp = self.battery_stamp
        report.voltage = _nan(battery.voltage_v)
        report.current = _nan(battery.current_a)
        report.temperature = _nan(battery.temperature_c)
        report.power_supply_status = current_status(report.current)
        report.present = True
        return report

    @staticmethod
    def _health(alarms: SmaAlarms) -> PowerSupplyHealth:
        active = alarms.active_alarms
        for name, health in ALARM_HEALTH:
            if name in active:
                return health
        return PowerSupplyHealth.UNSPEC_FAILURE if active else PowerSupplyHealth.GOOD

    def _diagnostic_report(self) -> DiagnosticReport:
        values = sma_values(self.readings)
        level = Level.OK
        parts: list[str] = []
        alarms = self.readings.get(SmaAlarms)
        if alarms is not None and alarms.active_alarms:
            level = Level.ERROR
            parts.append('alarms ' + ', '.join(alarms.active_alarms))
        if alarms is not None and alarms.active_warnings:
            level = max(level, Level.WARN)
            parts.append('warnings ' + ', '.join(alarms.active_warnings))
        if alarms is None:
            parts.append('no alarm frame (0x35A) yet')
        elif level == Level.OK:
            parts.append('OK')
        battery = self.readings.get(SmaBattery)
        soc = self.readings.get(SmaSoc)
        if battery is not None:
            summary = (f'{_fmt(battery.voltage_v, "V")}, {_fmt(battery.current_a, "A")}')
            if soc is not None:
                summary = f'SoC {_fmt(soc.soc_pct, "%")}, ' + summary
            parts.append(summary)
        return DiagnosticReport(level, '; '.join(parts), values)
