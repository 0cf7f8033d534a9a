# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The values sensor_msgs/BatteryState and diagnostic_msgs/DiagnosticStatus define, as enums.

Plain Python, byte for byte the messages' constants, so protocol code (a DBC mapping's rules,
the simulators) can name them without ROS; ``devices.base`` re-exports them for the devices.
"""
from __future__ import annotations

import enum


class Level(enum.IntEnum):
    """diagnostic_msgs/DiagnosticStatus levels (same byte values)."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


class PowerSupplyStatus(enum.IntEnum):
    """sensor_msgs/BatteryState POWER_SUPPLY_STATUS_* values."""

    UNKNOWN = 0
    CHARGING = 1
    DISCHARGING = 2
    NOT_CHARGING = 3
    FULL = 4


class PowerSupplyHealth(enum.IntEnum):
    """sensor_msgs/BatteryState POWER_SUPPLY_HEALTH_* values."""

    UNKNOWN = 0
    GOOD = 1
    OVERHEAT = 2
    DEAD = 3
    OVERVOLTAGE = 4
    UNSPEC_FAILURE = 5
    COLD = 6
    WATCHDOG_TIMER_EXPIRE = 7
    SAFETY_TIMER_EXPIRE = 8


class PowerSupplyTechnology(enum.IntEnum):
    """sensor_msgs/BatteryState POWER_SUPPLY_TECHNOLOGY_* values."""

    UNKNOWN = 0
    NIMH = 1
    LION = 2
    LIPO = 3
    LIFE = 4
    NICD = 5
    LIMN = 6
