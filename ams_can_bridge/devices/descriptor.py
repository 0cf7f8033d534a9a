# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What the bridge knows of one device type, in one place: a :class:`DeviceType`.

Every layer that lists device types reads these: the registry (``registry.py``: which class a
``<name>.type`` builds), the ``simulator`` (its device list), ``probe`` (its recognisers),
the bridge's ``--help``, the parameter and service reference pages and
``security/policy.xml`` (``scripts/policy_xml.py``). A descriptor names its classes as lazy
``'package.module:Name'`` strings, so that reading every descriptor imports no device code:
a node that only listens to a BMS16 never imports the AMS code.

A descriptor is found through the Python entry-point group ``ams_can_bridge.devices``
(``registry.py``); another package adds a device type by registering its own there
(doc/new_device.md).
"""
from __future__ import annotations

from dataclasses import dataclass
import importlib
from typing import Any

from ams_can_bridge.errors import ConfigError

ENTRY_POINT_GROUP = 'ams_can_bridge.devices'


def load(path: str) -> Any:
    """Import 'package.module:Name' and return Name."""
    module, _, name = path.partition(':')
    return getattr(importlib.import_module(module), name)


@dataclass(frozen=True)
class Variant:
    """One wire form of a device type that has several: '<name>.variant' picks it."""

    name: str
    device: str  # 'package.module:Class' of its Device subclass
    simulator: str | None = None  # 'package.module:Class' of its simulator, if it has one


@dataclass(frozen=True)
class DeviceType:
    """
    One device type: its name and where its code lives (lazy 'module:Name' strings).

    ``device`` is the Device subclass (its ``PARAMS`` and ``COMMANDS`` rows are the type's
    parameters and services); ``protocol`` the module of its wire format; ``simulator`` the
    simulator class (None: not simulated); ``recognisers`` probe's functions
    ``(traffic, found so far) -> new candidates``, run in the types' order. ``variants``:
    the wire forms of a type with several (the first is the default; ``device`` and
    ``simulator`` name the default's classes), described by ``variant_help``.
    ``simulated_by_default``: the ``simulator`` runs it when ``--devices`` is not given (off
    unless said: installing a plugin does not change what ``simulator`` alone sends).
    ``rank`` orders the types (the built-in ones first; a plugin's default comes after them,
    then by name): the order of every list above, and the simulator's start order.
    """

    name: str
    device: str
    protocol: str = ''
    simulator: str | None = None
    recognisers: tuple[str, ...] = ()
    variants: tuple[Variant, ...] = ()
    variant_help: str = ''
    simulated_by_default: bool = False
    rank: int = 1000

    def variant(self, name: str) -> Variant:
        """Return the variant of that name, or raise ConfigError naming the ones there are."""
        for variant in self.variants:
            if variant.name == name:
                return variant
        raise ConfigError(f'{self.name} has no variant {name!r}' + (
            ': use one of ' + ', '.join(self.variant_names) if self.variants else ''))

    @property
    def variant_names(self) -> tuple[str, ...]:
        """Return the names of its variants (the default first; empty: one wire form)."""
        return tuple(v.name for v in self.variants)

    def device_class(self, variant: str | None = None) -> Any:
        """Import and return its Device subclass (of a variant)."""
        return load(self.device if variant is None else self.variant(variant).device)

    def simulator_class(self, variant: str | None = None) -> Any:
        """Import and return its simulator class (of a variant); None if it has none."""
        path = self.simulator if variant is None else self.variant(variant).simulator
        return None if path is None else load(path)

    def params(self, variant: str | None = None) -> list[Any]:
        """Return its per-instance parameter specs (the ParamSpec rows of its device)."""
        from ams_can_bridge.devices.base import device_params
        return list(device_params(self.device_class(variant)))

    def commands(self, variant: str | None = None) -> tuple[Any, ...]:
        """Return its command rows (``Device.COMMANDS``): one service each."""
        return tuple(self.device_class(variant).COMMANDS)
