"""
SMA Sunny Island protocol BMS state: 0x351..0x35F and its dialects -> BatteryState, diagnostics.

Fixed IDs (no base_id). The primary frame is 0x356 (voltage, current, temperature); SoC comes
from 0x355 (the high-resolution SoC only where it agrees with the integer one: real BMSs put
zeros there), capacity from 0x35F, and charge = capacity x SoC while both are known and
fresh (NaN otherwise). The wire current is already positive while charging, the ROS sign.
"Not available" markers become NaN.

Commands: the only frame this device sends is the inverter keep-alive 0x305
(``inverter_keepalive``, devices/sma_keepalive.py), while commands are enabled.

Dialects (``protocols.sma_dialects``): Pylontech-style BMSs send their alarms in 0x359
instead of 0x35A; an active 0x359 alarm is ERROR and a warning WARN, exactly as in 0x35A,
and both feed the health. 0x35C (charge / discharge enable, charge requests), the module
counts (0x359, 0x372), the Victron name and cell ids, the energy counters (0x378), installed
capacity (0x379), product name (0x382) and the online status (0x35A byte 7) are diagnostics
values. Victron's 0x373 (min/max cell voltage and temperature) is shown in V and degC and
gives BatteryState.temperature (the hottest cell) when 0x356 carries none.

Every frame (group) expires on its own: a value older than ``stale_timeout`` is unknown
again (NaN, left out of the diagnostics values and listed under 'frames expired'), so a BMS
that keeps sending 0x356 but stops sending 0x35A never shows old alarms as current. The
identity frames (0x35E, 0x35F, 0x370, 0x371) come slowly and keep for IDENTITY_TIMEOUT.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Hashable, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, Device, DiagnosticReport, Level, NAN, PowerSupplyHealth, Sent)
from ams_can_bridge.devices.config import DeviceConfig
from ams_can_bridge.devices.sma_keepalive import InverterKeepalive, KEEPALIVE_PERIOD
from ams_can_bridge.devices.timed import TimedStore
from ams_can_bridge.parameters import ParamSpec
from ams_can_bridge.devices.ports import SendFrame
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.sma import (
    ALARMS_ID, BATTERY_ID, INFO_ID, LIMITS_ID, MANUFACTURER_ID, SmaAlarms, SmaBattery,
    SmaBatteryInfo, SmaCodec, SmaLimits, SmaManufacturer, SmaSoc, SOC_ID)
from ams_can_bridge.protocols.sma_dialects import (
    CELL_ID_KINDS, PYLONTECH_ALARMS_ID, PYLONTECH_CONDITION_NAMES, PYLONTECH_REQUEST_ID,
    PylontechAlarms, PylontechRequest, VICTRON_BMS_NAME1_ID, VICTRON_CELL_EXTREMES_ID,
    VICTRON_ENERGY_ID, VICTRON_INSTALLED_CAPACITY_ID, VICTRON_MIN_VOLTAGE_CELL_ID,
    VICTRON_MODULES_ID, VICTRON_PRODUCT_NAME_ID, VictronBmsName, VictronCellExtremes,
    VictronCellId, VictronEnergy, VictronInstalledCapacity, VictronModules, VictronProductName,
    keepalive_frame)

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
    VictronModules: VICTRON_MODULES_ID, VictronCellExtremes: VICTRON_CELL_EXTREMES_ID,
    **{(VictronCellId, kind): VICTRON_MIN_VOLTAGE_CELL_ID + k
       for k, kind in enumerate(CELL_ID_KINDS)},
    VictronEnergy: VICTRON_ENERGY_ID, VictronInstalledCapacity: VICTRON_INSTALLED_CAPACITY_ID,
    VictronProductName: VICTRON_PRODUCT_NAME_ID,
}
IDENTITY_GROUPS = frozenset({SmaManufacturer, SmaBatteryInfo, (VictronBmsName, 1),
                             (VictronBmsName, 2), VictronEnergy, VictronInstalledCapacity,
                             VictronProductName})
ONLINE_TEXT = {True: 'online', False: 'offline', None: 'not sent'}
ALARM_GROUPS = (SmaAlarms, PylontechAlarms)


def group_key(reading: Any) -> Hashable:
    """Return the key a reading is kept under: its type, with the part for Victron texts."""
    if isinstance(reading, VictronBmsName):
        return (VictronBmsName, reading.part)
    if isinstance(reading, VictronCellId):
        return (VictronCellId, reading.kind)
    # a class is hashable; mypy checks type[...] against Hashable's __hash__ too strictly
    return type(reading)  # type: ignore[return-value]


def _fmt(value: float | int | None, unit: str = '') -> str:
    if value is None:
        return 'not available'
    return f'{value:g}' + (f' {unit}' if unit else '')


def _fixed(value: float | None, decimals: int) -> str:
    return 'not available' if value is None else f'{value:.{decimals}f}'


def _nan(value: float | int | None) -> float:
    return NAN if value is None else float(value)


def _yes(flag: bool) -> str:
    return 'yes' if flag else 'no'


def _fixed2(value: float | None) -> str:
    return _fixed(value, 2)


def _fixed3(value: float | None) -> str:
    return _fixed(value, 3)


# The plain fields of each message as diagnostics values: (label, attribute, format), per
# group key, in the order shown. Alarms, names and cell ids follow in sma_values().
_FIELDS: tuple[tuple[Hashable, tuple[tuple[str, str, Callable[[Any], str]], ...]], ...] = (
    (SmaLimits, (('charge voltage limit V', 'charge_voltage_v', _fmt),
                 ('charge current limit A', 'charge_current_a', _fmt),
                 ('discharge current limit A', 'discharge_current_a', _fmt),
                 ('discharge voltage limit V', 'discharge_voltage_v', _fmt))),
    (SmaSoc, (('soc %', 'soc_pct', _fmt), ('soh %', 'soh_pct', _fmt),
              ('soc high resolution %', 'soc_hires_pct', _fmt))),
    (SmaBattery, (('voltage V', 'voltage_v', _fmt),
                  ('current A (positive = charging)', 'current_a', _fmt),
                  ('temperature degC', 'temperature_c', _fmt))),
    (SmaManufacturer, (('manufacturer', 'name', str),)),
    (SmaBatteryInfo, (('battery type', 'battery_type', _fmt),
                      ('bms version', 'bms_version', _fmt),
                      ('capacity Ah', 'capacity_ah', _fmt))),
    (PylontechRequest, (('charge enable', 'charge_enable', _yes),
                        ('discharge enable', 'discharge_enable', _yes),
                        ('request charge immediately', 'request_charge_immediately', _yes),
                        ('force charge request II', 'force_charge_request_ii', _yes),
                        ('full charge request', 'full_charge_request', _yes))),
    (VictronModules, (('modules OK', 'ok', _fmt),
                      ('modules blocking charge', 'blocking_charge', _fmt),
                      ('modules blocking discharge', 'blocking_discharge', _fmt),
                      ('modules offline', 'offline', _fmt))),
    (VictronCellExtremes, (('min cell voltage V', 'min_cell_v', _fixed3),
                           ('max cell voltage V', 'max_cell_v', _fixed3),
                           ('min cell temperature degC', 'min_temperature_c', _fixed2),
                           ('max cell temperature degC', 'max_temperature_c', _fixed2))),
    (VictronEnergy, (('energy charged kWh', 'charged_kwh', _fmt),
                     ('energy discharged kWh', 'discharged_kwh', _fmt))),
    (VictronInstalledCapacity, (('installed capacity Ah', 'capacity_ah', _fmt),)),
    (VictronProductName, (('product name', 'text', str),)),
)


def sma_values(readings: Mapping[Any, Any], prefix: str = '') -> dict[str, str]:
    """
    Diagnostic values of every SMA message in readings (keyed by ``group_key``).

    The readings are of every message type at once: the key (the type) tells which, so the
    values are typed Any here.
    """
    values: dict[str, str] = {}
    for key, fields in _FIELDS:
        reading = readings.get(key)
        if reading is not None:
            for label, attribute, show in fields:
                values[prefix + label] = show(getattr(reading, attribute))
    alarms = readings.get(SmaAlarms)
    if alarms is not None:
        values[prefix + 'alarms active'] = ', '.join(alarms.active_alarms) or 'none'
        values[prefix + 'warnings active'] = ', '.join(alarms.active_warnings) or 'none'
        values[prefix + 'system status (0x35A byte 7)'] = ONLINE_TEXT[alarms.online]
        for name, flag in alarms.alarms.items():
            values[f'{prefix}alarm {name}'] = flag.name
        for name, flag in alarms.warnings.items():
            values[f'{prefix}warning {name}'] = flag.name
    pylon = readings.get(PylontechAlarms)
    if pylon is not None:
        values[prefix + 'alarms active (0x359)'] = ', '.join(pylon.active_alarms) or 'none'
        values[prefix + 'warnings active (0x359)'] = ', '.join(pylon.active_warnings) or 'none'
        for name in PYLONTECH_CONDITION_NAMES:
            for kind, active in (('alarm', pylon.alarms), ('warning', pylon.warnings)):
                values[f'{prefix}{kind} {name} (0x359)'] = 'ACTIVE' if name in active else 'OK'
        values[prefix + 'module count'] = _fmt(pylon.module_count)
    parts = [readings.get((VictronBmsName, p)) for p in (1, 2)]
    if any(parts):
        values[prefix + 'bms name'] = ''.join(p.text if p else '' for p in parts)
    for kind in CELL_ID_KINDS:
        cell_id = readings.get((VictronCellId, kind))
        if cell_id is not None:
            values[f'{prefix}{kind.replace("_", " cell ")} id'] = cell_id.text
    return values


class SmaDevice(Device):
    """One BMS speaking the SMA Sunny Island protocol or its Pylontech / Victron dialects."""

    TYPE = 'sma'
    # Typical SMA-protocol BMSs send every 1 s (the BMS16 at 4 Hz): the default stale
    # timeout of 5 periods (5 s) must not flap on a 1 Hz sender.
    BROADCAST_PERIOD = 1.0
    DEFAULT_BASE_ID = None
    PARAMS = []
    COMMAND_PARAMS = [
        ParamSpec('inverter_keepalive', bool, False,
                  'send the inverter keep-alive 0x305 (8 zero bytes) every '
                  f'{KEEPALIVE_PERIOD:g} s while commands_enabled, for BMSs that wait for an '
                  'inverter (Pylontech protocol); false = never', read_only=False),
    ]

    def __init__(self, name: str, config: DeviceConfig | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, config, clock)
        self.codec = SmaCodec()
        self.readings: TimedStore[Hashable, Any] = TimedStore()  # by group_key: its type
        self.battery_stamp = NAN
        self.keepalive: InverterKeepalive | None = None  # made by attach_keepalive()

    # --- commands ------------------------------------------------------------------------
    def keepalive_frame(self) -> Frame:
        """Build the inverter keep-alive 0x305 the bridge sends in the inverter's place."""
        return keepalive_frame()

    def sent_ids(self, config: DeviceConfig | None = None) -> dict[tuple[int, bool], Sent]:
        """Return the keep-alive's ID while inverter_keepalive is true, else nothing."""
        if not (config or self.config).inverter_keepalive:
            return {}
        frame = self.keepalive_frame()
        return {(frame.arbitration_id, frame.is_extended_id): Sent('inverter keep-alive', True)}

    def attach_keepalive(self, send: SendFrame,
                         log: Callable[[str], None],
                         period: float = KEEPALIVE_PERIOD) -> InverterKeepalive:
        """
        Make this device's (disarmed) keep-alive sending through ``send``.

        It follows ``inverter_keepalive`` on every configure(); the caller arms it while
        commands are enabled.
        """
        self.keepalive = InverterKeepalive(self.keepalive_frame, send, log, self.name, period)
        self.keepalive.set_enabled(bool(self.config.inverter_keepalive))
        return self.keepalive

    def configure(self, changes: Mapping[str, Any]) -> DeviceConfig:
        """Apply parameter changes; the keep-alive follows inverter_keepalive at once."""
        new = super().configure(changes)
        if self.keepalive is not None:  # outside the device lock: stopping joins a thread
            self.keepalive.set_enabled(bool(new.inverter_keepalive))
        return new

    def _handle(self, reading: Any, stamp: float) -> bool:
        key = group_key(reading)
        self.readings.put(key, reading, self.clock())
        if isinstance(reading, SmaBattery):
            self.battery_stamp = stamp
            return True
        return False

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
        info = readings.get(SmaBatteryInfo)
        if info is not None:
            report.capacity = report.design_capacity = _nan(info.capacity_ah)
            # Remaining Ah only where both are known and fresh: NaN times anything is NaN.
            report.charge = report.capacity * report.percentage
        if any(k in readings for k in ALARM_GROUPS):
            report.power_supply_health = self._health(readings)
        battery = readings.get(SmaBattery)
        if battery is None:
            return report
        report.stamp = self.battery_stamp
        report.voltage = _nan(battery.voltage_v)
        report.current = _nan(battery.current_a)
        report.temperature = _nan(battery.temperature_c)
        cells = readings.get(VictronCellExtremes)
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
        level = Level.OK
        parts: list[str] = []
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
        elif level == Level.OK:
            parts.append('OK')
        battery = readings.get(SmaBattery)
        soc = readings.get(SmaSoc)
        if battery is not None:
            summary = (f'{_fmt(battery.voltage_v, "V")}, {_fmt(battery.current_a, "A")}')
            if soc is not None:
                summary = f'SoC {_fmt(soc.soc_pct, "%")}, ' + summary
            parts.append(summary)
        return DiagnosticReport(level, '; '.join(parts), values)
