# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
EVMS3 error codes -> BatteryState health and diagnostic words, and when a write is allowed.

From ZEVA's open EVMS3 firmware (doc/protocols.md section 3.1): warnings 2, 4, 6 and 10 let
the vehicle go on; in stationary mode (setting 29) the firmware opens the main contactor on
warning 4 (low cell) and disables charging on warning 6 (high cell), so those are not GOOD.
ZEVA's Monitor offers setup only from IDLE: the configuration is written only in IDLE/SETUP.
"""
from __future__ import annotations

from ams_can_bridge.devices.base import PowerSupplyHealth
from ams_can_bridge.protocols.evms3 import Evms3Error, Evms3State, EVMS3_WARNINGS

WRITABLE_STATES = (Evms3State.IDLE, Evms3State.SETUP)
# Stationary mode (setting 29): what the EVMS3 firmware does on these warnings.
STATIONARY_ACTIONS = {
    Evms3Error.LOW_CELL_WARNING: 'main contactor opened (stationary mode)',
    Evms3Error.HIGH_CELL_WARNING: 'charging disabled (stationary mode)',
}

_HEALTH = {
    Evms3Error.BMS_SHUTDOWN: PowerSupplyHealth.DEAD,
    Evms3Error.HIGH_CELL_WARNING: PowerSupplyHealth.OVERVOLTAGE,
    Evms3Error.BMS_ENDED_CHARGE: PowerSupplyHealth.OVERVOLTAGE,
    Evms3Error.BMS_OVER_TEMP: PowerSupplyHealth.OVERHEAT,
    Evms3Error.OVERTEMPERATURE: PowerSupplyHealth.OVERHEAT,
    Evms3Error.BMS_UNDER_TEMP: PowerSupplyHealth.COLD,
}


def error_health(error: Evms3Error, stationary: bool | None = False) -> PowerSupplyHealth:
    """Map an EVMS3 error code to sensor_msgs power_supply_health."""
    if stationary and error == Evms3Error.LOW_CELL_WARNING:
        return PowerSupplyHealth.DEAD  # undervoltage: the pack is disconnected
    if error in _HEALTH:
        return _HEALTH[error]
    if error == Evms3Error.NONE or error in EVMS3_WARNINGS:
        return PowerSupplyHealth.GOOD
    return PowerSupplyHealth.UNSPEC_FAILURE


def error_text(error: Evms3Error, stationary: bool | None = False) -> str:
    """Say 'no error', 'warning NAME (n)' or 'error NAME (n)', with what stationary mode does."""
    if error == Evms3Error.NONE:
        return 'no error'
    kind = 'warning' if error in EVMS3_WARNINGS else 'error'
    text = f'{kind} {error.name} ({int(error)})'
    if stationary and error in STATIONARY_ACTIONS:
        text += ': ' + STATIONARY_ACTIONS[error]
    return text
