# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The diagnostic key/value table of an AMS device: every decoded field, named for a reader.

Split from ``devices/ams/device.py`` (the state machine and the command side) to keep each file
readable; called by ``status.diagnostic_report`` with the device lock held.
"""
from __future__ import annotations

import math
from typing import Any

from ams_can_bridge.protocols import ams as proto


def _fmt(value: float, digits: int = 3) -> str:
    return 'unknown' if value != value else f'{value:.{digits}f}'


def diagnostic_values(self: Any) -> dict[str, str]:
    """Build the AMS device's diagnostic key/value table (its lock held)."""
    values: dict[str, str] = {
        'state': self.state.name,
        'status frames': str(self.status_seq),
        'bank count (configured)': str(self.bank_count),
        'active errors': self._error_text() or 'none',
        'last error': (f'{self.last_error.name} at tick {self._last_error_tick}'
                       if self.last_error else 'none'),
        'error events': str(self.error_seq),
        'counter repeats': str(self.counter.repeats),
        'frames lost (counter jumps)': str(self.counter.lost),
        'frames beyond bank count': str(self._beyond_banks),
        'current sensor': getattr(self.current_sensor, 'name', '') or 'none',
    }
    if self.current_sensor_origin:
        values['current sensor chosen by'] = self.current_sensor_origin
    if self.current_sensor is not None:
        values['pack voltage channel'] = str(self.config.pack_voltage_channel or 'U1')
    repeater = self.charger
    if repeater is not None:  # what the bridge itself sends in the charger role
        values['charger START repeated'] = (
            f'yes, every {repeater.period * 1000:g} ms ({repeater.frames_sent} sent)'
            if repeater.active else 'no' + (f' (last: {repeater.last_stop})'
                                            if repeater.last_stop else ''))
    capacity = self.config.design_capacity_ah
    values['design capacity (Ah)'] = 'unset' if capacity is None else f'{float(capacity):g}'
    status = self._status
    if status is not None:
        word = status.status
        for field in ('air_plus', 'air_minus', 'precharge', 'warn_volt', 'warn_temp',
                      'hvdc_interlock', 'imd_error', 'ams_error'):
            values[field] = str(getattr(word, field)).lower()
        values.update({
            'bank count (AMS)': str(word.bank_count),
            'volt_min (V)': f'{status.volt_min_v:.2f}',
            'temp_max (degC)': str(status.temp_max_c),
            'SOC (%)': str(status.soc_pct),
            'counter': str(status.counter),
            'relay error AIR-': str(status.relay_error_air_minus).lower(),
            'relay error AIR+': str(status.relay_error_air_plus).lower(),
            'relay error precharge': str(status.relay_error_precharge).lower(),
        })
    cells = self._cell_list()
    known = [c for c in cells if c == c]
    values['cells received'] = f'{len(known)}/{len(cells)}'
    if known:
        values['cell min (V)'] = f'{min(known):.2f}'
        values['cell max (V)'] = f'{max(known):.2f}'
        values['cell sum (V)'] = f'{math.fsum(known):.2f}'
    temps = [t for t in self._temp_list() if t == t]
    if temps:
        values['cell temperature min/max (degC)'] = f'{min(temps):g}/{max(temps):g}'
    charger = self._fresh(proto.AmsChargerStatus)
    if charger is not None:
        values['charger status: SOC (%)'] = str(charger.soc_pct)
        values['charger status: current (A)'] = _fmt(charger.charger_current_a, 1)
        values['charger status: turn on charger'] = str(charger.charger_on).lower()
    car = self._fresh(proto.CarStatus)
    if car is not None:
        values['car status: command'] = car.command.name
        values['car status: bank count'] = str(car.bank_count)
        values['car status: counter'] = str(car.counter)
    command = self._fresh(proto.ChargerCommand)
    if command is not None:
        values['charger command'] = f'{command.start.name} at tick {command.time_tick}'
    return values
