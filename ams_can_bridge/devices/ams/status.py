# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What an AMS's state means: its power_supply_health, its diagnostic level and message.

Split from ``devices/ams/device.py`` (the frames, the banks, the IVT-S link and the command side),
which keeps the state; this reads it and holds none of its own. Called with the device lock
held (``_battery_report``, ``_diagnostic_report``).

Error bookkeeping: an AMS error event (0x014) stays *active* until the AMS next returns
from ERROR / CHARGE_ERROR to another state (``AmsDevice._on_status``), so a short error is
not missed between two diagnostics publications; the most recent active error decides the
health.
"""
from __future__ import annotations

from typing import Sequence, TYPE_CHECKING

from ams_can_bridge.devices.ams.values import diagnostic_values
from ams_can_bridge.devices.base import DiagnosticReport, Level, PowerSupplyHealth
from ams_can_bridge.protocols import ams as proto
from ams_can_bridge.protocols.ams import AmsError, AmsState

if TYPE_CHECKING:  # ams.py imports this module
    from ams_can_bridge.devices.ams.device import AmsDevice

ERROR_STATES = (AmsState.ERROR, AmsState.CHARGE_ERROR)
HEALTH_OF_ERROR = {
    AmsError.CELL_VOLTAGE_HIGH: PowerSupplyHealth.OVERVOLTAGE,
    AmsError.CELL_VOLTAGE_LOW: PowerSupplyHealth.DEAD,
    AmsError.CELL_TEMP_HIGH: PowerSupplyHealth.OVERHEAT,
    AmsError.CELL_TEMP_LOW: PowerSupplyHealth.COLD,
}


def health(status: proto.AmsStatus | None, state: AmsState,
           active_errors: Sequence[AmsError]) -> PowerSupplyHealth:
    """Return the pack's health: the latest active error, else the state and error bits."""
    if status is None:
        return PowerSupplyHealth.UNKNOWN
    if active_errors:
        return HEALTH_OF_ERROR.get(active_errors[-1], PowerSupplyHealth.UNSPEC_FAILURE)
    word = status.status
    if state in ERROR_STATES or word.ams_error or word.imd_error:
        return PowerSupplyHealth.UNSPEC_FAILURE
    return PowerSupplyHealth.GOOD


def error_text(active_errors: Sequence[AmsError]) -> str:
    """Return the active errors as the diagnostics name them, oldest first."""
    return ', '.join(e.name for e in active_errors)


def relays_text(word: proto.AmsStatusWord) -> str:
    """Return the relays as 'AIR+ closed, AIR- open, precharge open'."""
    return ', '.join(f'{label} {"closed" if closed else "open"}' for label, closed in (
        ('AIR+', word.air_plus), ('AIR-', word.air_minus), ('precharge', word.precharge)))


def diagnostic_report(device: AmsDevice, with_values: bool = True) -> DiagnosticReport:
    """Build the AMS device's DiagnosticReport (its lock held)."""
    status = device._status
    if status is None:
        return DiagnosticReport(Level.STALE, 'no AMS status received yet',
                                diagnostic_values(device) if with_values else {})
    word = status.status
    name, state, banks = device.name, device.state, device.bank_count
    errors, warnings = [], []
    if state in ERROR_STATES:
        errors.append(f'AMS in {state.name}')
    if device._active_errors:
        errors.append('errors: ' + error_text(device._active_errors))
    if word.ams_error:
        errors.append('AMS error bit set')
    if word.imd_error:
        errors.append('IMD error')
    if word.warn_volt:
        warnings.append('cell voltage close to its limits')
    if word.warn_temp:
        warnings.append('cell temperature close to its limits')
    counter = device.counter
    if counter.repeat_run:
        warnings.append(f'status counter stuck at {status.counter} '
                        f'({counter.repeat_run} repeated frames)')
    elif counter.recovering and counter.lost:
        warnings.append(f'status counter jumped: {counter.lost} frames lost so far')
    if device._beyond_banks:
        warnings.append(f'{device._beyond_banks} frames from bank(s) up to '
                        f'{device._highest_bank} beyond {name}.bank_count = {banks}: '
                        f'set {name}.bank_count to {device._highest_bank}')
    if word.bank_count != banks:
        warnings.append(f'AMS reports {word.bank_count} bank(s), {name}.bank_count = {banks}')
    if status.soc_pct > 100:
        warnings.append(f'SOC {status.soc_pct} % out of range (shown as unknown)')
    level = Level.ERROR if errors else Level.WARN if warnings else Level.OK
    message = '; '.join([f'{state.name}', relays_text(word)] + errors + warnings)
    return DiagnosticReport(level, message, diagnostic_values(device) if with_values else {})
