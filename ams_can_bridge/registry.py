# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Which device types are installed: the descriptors under the entry-point group.

Every package (this one included, setup.py) registers its device types under the Python
entry-point group ``ams_can_bridge.devices``: ``<type name> = package.module:DESCRIPTOR``, a
:class:`~ams_can_bridge.devices.descriptor.DeviceType`. They are read once, at import, with
importlib.metadata; loading one imports only its descriptor's module (the classes are lazy
'module:Class' strings), so a node that only listens to a BMS16 never imports the AMS code.

A plugin that fails to load (its module raises, the entry point names no DeviceType, or a
name taken already) is no crash: it is left out, logged as a warning, and named in the error
of an instance that asks for it. The tables below (``DEVICE_TYPES``, ``DEVICES``,
``SIMULATORS``, ``VARIANTS``, ``VARIANT_HELP``) are views of the descriptors.
"""
from __future__ import annotations

from importlib.metadata import entry_points, EntryPoint
import logging
from typing import Any, Iterable

from ams_can_bridge.devices.builtin import BUILT_IN
from ams_can_bridge.devices.descriptor import DeviceType, ENTRY_POINT_GROUP, load
from ams_can_bridge.errors import ConfigError

__all__ = ['BROKEN', 'DESCRIPTORS', 'DEVICE_TYPES', 'DEVICES', 'SIMULATORS', 'VARIANTS',
           'VARIANT_HELP', 'descriptor', 'device_class', 'discover', 'load', 'simulator_class']


Discovered = tuple[dict[str, DeviceType], dict[str, str]]


def discover(found: Iterable[EntryPoint],
             built_in: Iterable[DeviceType] = BUILT_IN) -> Discovered:
    """
    Load the descriptors of the entry points: ({name: descriptor} in order, {name: why not}).

    The built-in descriptors are always there (a source checkout may run without installed
    metadata); an entry point naming one of them again (this package's own registration, or
    two installs on the path) adds nothing. Order: ``rank``, then name.
    """
    types = {d.name: d for d in built_in}
    broken: dict[str, str] = {}
    for point in found:
        if point.name in broken:
            continue
        origin = f'entry point {point.name} = {point.value}' + (
            f' (distribution {point.dist.name})' if point.dist is not None else '')
        try:
            loaded = point.load()
        except Exception as exc:  # any plugin bug: reported, never a crash of the bridge
            broken[point.name] = f'{origin} failed to load: {type(exc).__name__}: {exc}'
            continue
        if not isinstance(loaded, DeviceType):
            broken[point.name] = (f'{origin} is a {type(loaded).__name__}, not an '
                                  'ams_can_bridge.devices.descriptor.DeviceType')
        elif loaded.name != point.name:
            broken[point.name] = (f'{origin} names its DeviceType {loaded.name!r}: the entry '
                                  'point and the descriptor must have the same name')
        elif point.name in types:
            if types[point.name] == loaded:  # registered twice (this package's own, two paths)
                continue
            if _is_built_in(point.name, built_in):
                broken[point.name] = (f'{origin}: {point.name!r} is a built-in device type; '
                                      'give the plugin a name of its own')
            else:  # two plugins of one name: neither is trusted
                broken[point.name] = f'{origin}: another installed package has that name too'
                del types[point.name]
        else:
            types[point.name] = loaded
    ordered = dict(sorted(types.items(), key=lambda item: (item[1].rank, item[0])))
    for name, why in broken.items():
        logging.getLogger(__name__).warning('device type %r not available: %s', name, why)
    return ordered, broken


def _is_built_in(name: str, built_in: Iterable[DeviceType]) -> bool:
    return any(d.name == name for d in built_in)


DESCRIPTORS, BROKEN = discover(entry_points(group=ENTRY_POINT_GROUP))
DEVICE_TYPES = tuple(DESCRIPTORS)
DEVICES = {name: d.device for name, d in DESCRIPTORS.items()}
SIMULATORS = {name: d.simulator for name, d in DESCRIPTORS.items() if d.simulator is not None}
# Device types with more than one wire form: '<name>.variant' picks the device and simulator
# classes (the first variant is the default; DEVICES / SIMULATORS name the default's classes).
VARIANTS = {name: {v.name: (v.device, v.simulator) for v in d.variants}
            for name, d in DESCRIPTORS.items() if d.variants}
# The description of '<name>.variant' (ros2 param describe, the parameter reference).
VARIANT_HELP = {name: d.variant_help for name, d in DESCRIPTORS.items() if d.variant_help}


def unknown(device_type: str) -> str:
    """Return why a device type is not there: the installed ones, or its plugin's failure."""
    if device_type in BROKEN:
        return f'device type {device_type!r} is installed but unusable: {BROKEN[device_type]}'
    return (f'unknown device type {device_type!r}: use one of ' + ', '.join(DEVICE_TYPES)
            + ' (the installed ones: entry points of the group ' + ENTRY_POINT_GROUP + ')')


def descriptor(device_type: str) -> DeviceType:
    """Return the descriptor of a device type, with a clear error if it is not installed."""
    if device_type not in DESCRIPTORS:
        raise ConfigError(unknown(device_type))
    return DESCRIPTORS[device_type]


def device_class(device_type: str, variant: str | None = None) -> Any:
    """Return the Device subclass for a type (and variant), with a clear error if unknown."""
    return descriptor(device_type).device_class(variant)


def simulator_class(device_type: str, variant: str | None = None) -> Any:
    """Return the simulator class for a type (and variant)."""
    cls = descriptor(device_type).simulator_class(variant)
    if cls is None:
        raise ConfigError(f'device type {device_type!r} has no simulator: simulate one of '
                          + ', '.join(SIMULATORS))
    return cls
