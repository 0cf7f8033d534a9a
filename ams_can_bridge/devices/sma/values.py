# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The SMA family's diagnostics values: every decoded field of 0x351..0x382, as text.

Shared by the sma device and the BMS16 (its SMA frames, with a prefix). The readings are
kept by ``devices.sma.device.group_key``: a reading's type, with the part / kind for Victron texts.
"""
from __future__ import annotations

from typing import Any, Callable, Hashable, Mapping

from ams_can_bridge.protocols.sma import (
    HIRES_AGREEMENT_PCT, HIRES_SCALES, SmaAlarms, SmaBattery, SmaBatteryInfo, SmaFlag,
    SmaLimits, SmaManufacturer, SmaSoc)
from ams_can_bridge.protocols.sma_dialects import (
    CELL_ID_KINDS, PYLONTECH_CONDITION_NAMES, PylontechAlarms, PylontechCellExtremes,
    PylontechCellIds, PylontechRequest, VictronBmsName, VictronCellExtremes, VictronCellId,
    VictronEnergy, VictronInstalledCapacity, VictronModules, VictronProductName)

ONLINE_TEXT = {True: 'online', False: 'offline', None: 'not sent'}
# a flag's name: an enum member's .name is a property call, ~60 of them a report
_FLAG_NAME = {flag: flag.name for flag in SmaFlag}


def fmt(value: float | int | None, unit: str = '') -> str:
    """Format a value as the diagnostics show it (None: not available)."""
    if value is None:
        return 'not available'
    return f'{value:g}' + (f' {unit}' if unit else '')


def _fixed(value: float | None, decimals: int) -> str:
    return 'not available' if value is None else f'{value:.{decimals}f}'


def _yes(flag: bool) -> str:
    return 'yes' if flag else 'no'


def _fixed2(value: float | None) -> str:
    return _fixed(value, 2)


def _fixed3(value: float | None) -> str:
    return _fixed(value, 3)


def _version(value: int | None) -> str:
    """
    Show 0x35F bytes 2-3 as their senders mean them: byte 2 major, byte 3 minor, each a number.

    A REC Q's 02 06 is its firmware 2.6, a BYD LVS's 01 17 its v1.23, diyBMS sends its build's
    year and week (doc/protocols.md 5.2); the bytes as sent follow.
    """
    if value is None:
        return 'not available'
    major, minor = value & 0xFF, value >> 8  # little-endian: byte 2 is the low byte
    return f'{major}.{minor} (bytes 2-3: {major:02X} {minor:02X})'


def _cell_id(value: int | None) -> str:
    return 'not available' if value is None else f'{value:04X}'  # module, cell: 0206


# The plain fields of each message as diagnostics values: (label, attribute, format), per
# group key, in the order shown. Alarms, names and cell ids follow in sma_values().
_FIELDS: tuple[tuple[Hashable, tuple[tuple[str, str, Callable[[Any], str]], ...]], ...] = (
    (SmaLimits, (('charge voltage limit V', 'charge_voltage_v', fmt),
                 ('charge current limit A', 'charge_current_a', fmt),
                 ('discharge current limit A', 'discharge_current_a', fmt),
                 ('discharge voltage limit V', 'discharge_voltage_v', fmt))),
    (SmaSoc, (('soc %', 'soc_pct', fmt), ('soh %', 'soh_pct', fmt))),
    (SmaBattery, (('voltage V', 'voltage_v', fmt),
                  ('current A (positive = charging)', 'current_a', fmt),
                  ('temperature degC', 'temperature_c', fmt))),
    (SmaManufacturer, (('manufacturer', 'name', str),)),
    (SmaBatteryInfo, (('battery type', 'battery_type', fmt),
                      ('bms version', 'bms_version', _version),
                      ('capacity Ah', 'capacity_ah', fmt))),
    (PylontechRequest, (('charge enable', 'charge_enable', _yes),
                        ('discharge enable', 'discharge_enable', _yes),
                        ('request charge immediately', 'request_charge_immediately', _yes),
                        ('force charge request II', 'force_charge_request_ii', _yes),
                        ('full charge request', 'full_charge_request', _yes))),
    (VictronModules, (('modules OK', 'ok', fmt),
                      ('modules blocking charge', 'blocking_charge', fmt),
                      ('modules blocking discharge', 'blocking_discharge', fmt),
                      ('modules offline', 'offline', fmt))),
    (VictronCellExtremes, (('min cell voltage V', 'min_cell_v', _fixed3),
                           ('max cell voltage V', 'max_cell_v', _fixed3),
                           ('min cell temperature degC', 'min_temperature_c', _fixed2),
                           ('max cell temperature degC', 'max_temperature_c', _fixed2))),
    (PylontechCellExtremes, (('max cell temperature degC (0x370)', 'max_temperature_c', fmt),
                             ('min cell temperature degC (0x370)', 'min_temperature_c', fmt),
                             ('max cell voltage V (0x370)', 'max_cell_v', _fixed3),
                             ('min cell voltage V (0x370)', 'min_cell_v', _fixed3))),
    (PylontechCellIds, (('max temperature cell (0x371)', 'max_temperature_cell', _cell_id),
                        ('min temperature cell (0x371)', 'min_temperature_cell', _cell_id),
                        ('max voltage cell (0x371)', 'max_voltage_cell', _cell_id),
                        ('min voltage cell (0x371)', 'min_voltage_cell', _cell_id))),
    (VictronEnergy, (('energy charged kWh', 'charged_kwh', fmt),
                     ('energy discharged kWh', 'discharged_kwh', fmt))),
    (VictronInstalledCapacity, (('installed capacity Ah', 'capacity_ah', fmt),)),
    (VictronProductName, (('product name', 'text', str),)),
)


def hires_values(soc: SmaSoc) -> dict[str, str]:
    """Show 0x355's high-resolution SoC: at the scale agreeing with the SoC, or why not."""
    raw = soc.hires_raw
    if raw is None:
        return {'soc high resolution %': 'not available'}
    scale = soc.hires_scale
    if scale is not None:
        return {'soc high resolution %': fmt(soc.hires_percent),
                'soc high resolution scale': f'{scale:g} %/bit (agrees with the SoC '
                                             f'{fmt(soc.soc_pct)} %)'}
    at = ', '.join(f'{raw / round(1 / s):g} % at {s:g} %/bit' for s in HIRES_SCALES)
    return {'soc high resolution %': f'not used: {raw} as sent ({at}) is not within '
                                     f'{HIRES_AGREEMENT_PCT:g} % of the SoC {fmt(soc.soc_pct)} %'}


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
    soc = readings.get(SmaSoc)
    if soc is not None:
        values.update({prefix + k: v for k, v in hires_values(soc).items()})
    alarms = readings.get(SmaAlarms)
    if alarms is not None:
        values[prefix + 'alarms active'] = ', '.join(alarms.active_alarms) or 'none'
        values[prefix + 'warnings active'] = ', '.join(alarms.active_warnings) or 'none'
        values[prefix + 'system status (0x35A byte 7)'] = ONLINE_TEXT[alarms.online]
        for name, flag in alarms.alarms.items():
            values[f'{prefix}alarm {name}'] = _FLAG_NAME[flag]
        for name, flag in alarms.warnings.items():
            values[f'{prefix}warning {name}'] = _FLAG_NAME[flag]
    pylon = readings.get(PylontechAlarms)
    if pylon is not None:
        values[prefix + 'alarms active (0x359)'] = ', '.join(pylon.active_alarms) or 'none'
        values[prefix + 'warnings active (0x359)'] = ', '.join(pylon.active_warnings) or 'none'
        for name in PYLONTECH_CONDITION_NAMES:
            for kind, active in (('alarm', pylon.alarms), ('warning', pylon.warnings)):
                values[f'{prefix}{kind} {name} (0x359)'] = 'ACTIVE' if name in active else 'OK'
        values[prefix + 'module count'] = fmt(pylon.module_count)
    parts = [readings.get((VictronBmsName, p)) for p in (1, 2)]
    if any(parts):
        values[prefix + 'bms name'] = ''.join(p.text if p else '' for p in parts)
    for kind in CELL_ID_KINDS:
        cell_id = readings.get((VictronCellId, kind))
        if cell_id is not None:
            values[f'{prefix}{kind.replace("_", " cell ")} id'] = cell_id.text
    return values
