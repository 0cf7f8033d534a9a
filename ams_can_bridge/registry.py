# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Where each device type lives: its state class (with its command rows) and its simulator.

Lazy 'module:Class' strings, so importing the registry costs nothing and a node that only
listens to a BMS16 never imports the AMS code.
"""
from __future__ import annotations

import importlib
from typing import Any

from ams_can_bridge.errors import ConfigError

DEVICE_TYPES = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma', 'dbc', 'pack')

DEVICES = {
    'ams': 'ams_can_bridge.devices.ams:AmsDevice',
    'ivt_s': 'ams_can_bridge.devices.ivt_s:IvtSDevice',
    'evms3': 'ams_can_bridge.devices.evms3:Evms3Device',
    'bms16': 'ams_can_bridge.devices.bms16:Bms16Device',
    'sma': 'ams_can_bridge.devices.sma:SmaDevice',
    'dbc': 'ams_can_bridge.devices.dbc:DbcDevice',
    'pack': 'ams_can_bridge.devices.pack.device:PackDevice',
}

SIMULATORS = {
    'ams': 'ams_can_bridge.sim.ams:AmsSimulator',
    'ivt_s': 'ams_can_bridge.sim.ivt_s:IvtSSimulator',
    'evms3': 'ams_can_bridge.sim.evms3:Evms3Simulator',
    'bms16': 'ams_can_bridge.sim.bms16:Bms16Simulator',
    'sma': 'ams_can_bridge.sim.sma:SmaSimulator',
    'dbc': 'ams_can_bridge.sim.dbc:DbcSimulator',
}

# Device types with more than one wire form: '<name>.variant' picks the device and simulator
# classes (the first variant is the default; DEVICES / SIMULATORS name the default's classes).
# BMS16: 'inverter' = the 11-bit / 500 kbit/s units "intended for CAN integration with
# inverters" (doc/protocols.md section 4), 'standard' = the EVMS3 protocol (section 6).
VARIANTS = {
    'bms16': {
        'inverter': ('ams_can_bridge.devices.bms16:Bms16Device',
                     'ams_can_bridge.sim.bms16:Bms16Simulator'),
        'standard': ('ams_can_bridge.devices.bms16_std:Bms16StdDevice',
                     'ams_can_bridge.sim.bms16_std:Bms16StdSimulator'),
    },
}
# The description of '<name>.variant' (ros2 param describe, the parameter reference).
VARIANT_HELP = {
    'bms16': ('wire form of the BMS16: inverter (11-bit, 500 kbit/s, IDs 500.. and the SMA '
              'frames; doc/protocols.md section 4) or standard (BMS16v2 standard form: EVMS3 '
              'protocol, 29-bit, 250 kbit/s; section 6), which has its own base_id default '
              'and config.* parameters'),
}


def load(path: str) -> Any:
    """Import 'package.module:Name' and return Name."""
    module, _, name = path.partition(':')
    return getattr(importlib.import_module(module), name)


def device_class(device_type: str, variant: str | None = None) -> Any:
    """Return the Device subclass for a type (and variant), with a clear error if unknown."""
    if device_type not in DEVICES:
        raise ConfigError(f'unknown device type {device_type!r}: use one of '
                          + ', '.join(DEVICE_TYPES))
    if variant is None:
        return load(DEVICES[device_type])
    return load(_variant(device_type, variant)[0])


def simulator_class(device_type: str, variant: str | None = None) -> Any:
    """Return the simulator class for a type (and variant)."""
    if variant is None:
        return load(SIMULATORS[device_type])
    return load(_variant(device_type, variant)[1])


def _variant(device_type: str, variant: str) -> tuple[str, str]:
    variants = VARIANTS.get(device_type, {})
    if variant not in variants:
        raise ConfigError(f'{device_type} has no variant {variant!r}'
                          + (': use one of ' + ', '.join(variants) if variants else ''))
    return variants[variant]
