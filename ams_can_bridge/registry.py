"""
Where each device type lives: state class, simulator class, ROS command services.

Lazy 'module:Class' strings, so importing the registry costs nothing and a node that only
listens to a BMS16 never imports the AMS code.
"""
from __future__ import annotations

import importlib
from typing import Any

DEVICE_TYPES = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma')

DEVICES = {
    'ams': 'ams_can_bridge.devices.ams:AmsDevice',
    'ivt_s': 'ams_can_bridge.devices.ivt_s:IvtSDevice',
    'evms3': 'ams_can_bridge.devices.evms3:Evms3Device',
    'bms16': 'ams_can_bridge.devices.bms16:Bms16Device',
    'sma': 'ams_can_bridge.devices.sma:SmaDevice',
}

SIMULATORS = {
    'ams': 'ams_can_bridge.sim.ams:AmsSimulator',
    'ivt_s': 'ams_can_bridge.sim.ivt_s:IvtSSimulator',
    'evms3': 'ams_can_bridge.sim.evms3:Evms3Simulator',
    'bms16': 'ams_can_bridge.sim.bms16:Bms16Simulator',
    'sma': 'ams_can_bridge.sim.sma:SmaSimulator',
}

# ROS command services per device type (issue: commanding); only these types have any.
COMMANDERS = {
    'ams': 'ams_can_bridge.ros.ams_commands:AmsCommands',
    'ivt_s': 'ams_can_bridge.ros.ivt_commands:IvtCommands',
    'evms3': 'ams_can_bridge.ros.zeva_commands:Evms3Commands',
    'bms16': 'ams_can_bridge.ros.zeva_commands:Bms16Commands',
}


def load(path: str) -> Any:
    """Import 'package.module:Name' and return Name."""
    module, _, name = path.partition(':')
    return getattr(importlib.import_module(module), name)


def device_class(device_type: str) -> Any:
    """Return the Device subclass for a type name, with a clear error for unknown types."""
    if device_type not in DEVICES:
        raise ValueError(f'unknown device type {device_type!r}: use one of '
                         + ', '.join(DEVICE_TYPES))
    return load(DEVICES[device_type])
