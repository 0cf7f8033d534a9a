# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A device instance's typed configuration: one frozen dataclass per device type.

The classes are written out in ``devices/generated_configs.py``, generated from the device types'
ParamSpecs (common, their own, their command services') by ``scripts/gen_device_configs.py``;
``test/test_device_configs.py`` fails when a parameter table and its class part. So the
parameter list stays the one source of names, types and defaults, and mypy checks every
``config.<field>`` read. A configuration is built and checked once from parameter values and
never changed in place: a parameter change builds a new one, the device checks it whole and
swaps it in with one assignment, so a reader on another thread sees the old set or the new
set, never half of each.

Fields are named as the parameter keys with dots as underscores
(``config.pack_capacity_ah`` -> ``config_pack_capacity_ah``); ``value(key)`` and
``replace({key: value})`` speak parameter keys for the generic code (node, log2bag).
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, ClassVar, Iterable, Mapping, Self

from ams_can_bridge.errors import EncodeRangeError, ParamError, RefusedCommand


def field_name(key: str) -> str:
    """Return the dataclass field of a parameter key ('config.cells' -> 'config_cells')."""
    return key.replace('.', '_')


@dataclasses.dataclass(frozen=True)
class DeviceConfig:
    """
    Base of the configuration classes (devices/generated_configs.py): the values every device has.

    A value given as None for a key that has a default takes the default (log2bag reads
    ``key: ~`` from a file as None; the node declares such a key with its default), so a
    field typed without None never holds None. Only the keys without a default stay unset.
    """

    KEYS: ClassVar[tuple[str, ...]] = (  # parameter keys, in declaration order
        'frame_id', 'location', 'serial_number', 'stale_timeout')

    frame_id: str = ''
    location: str = ''
    serial_number: str = ''
    stale_timeout: float = 5.0

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> Self:
        """Build from {parameter key: value}; keys left out take their declared default."""
        cls._check_keys(values)
        return cls(**{field_name(k): cls._normal(k, v) for k, v in values.items()})

    @classmethod
    def _check_keys(cls, values: Iterable[str]) -> None:
        unknown = set(values) - set(cls.KEYS)
        if unknown:
            raise ParamError('unknown parameter(s): ' + ', '.join(sorted(unknown)))

    @classmethod
    def _normal(cls, key: str, value: Any) -> Any:
        default = cls.__dataclass_fields__[field_name(key)].default
        if value is None:
            return default  # None for a key without a default: unset
        if isinstance(value, list):
            # YAML [] cannot be told from unset: a key without default stays unset
            value = None if not value and default is None else tuple(value)
        return value

    def value(self, key: str) -> Any:
        """Return the value of a parameter key."""
        return getattr(self, field_name(key))

    def replace(self, changes: Mapping[str, Any]) -> Self:
        """Return a new configuration with these {parameter key: value} changes."""
        self._check_keys(changes)
        return dataclasses.replace(
            self, **{field_name(k): self._normal(k, v) for k, v in changes.items()})


class ConfigFields:
    """
    A device's ``config.<field>`` values (ZEVA): checked by the protocol, all needed to write.

    The protocol module lists the fields (``CONFIG_FIELDS``) and checks one value
    (``check_config_value``); the values have no defaults, since a guess written to the device
    would overwrite its real setting.
    """

    PREFIX = 'config.'

    def __init__(self, fields: Iterable[Any], check: Callable[[str, Any], Any]) -> None:
        """Keep the protocol's fields and its check(field, value) -> normalized value."""
        self.names = tuple(f.name for f in fields)
        self._check = check

    def problems(self, instance: str, config: DeviceConfig,
                 keys: Iterable[str] | None = None) -> list[str]:
        """Name every set value the protocol refuses, with what it allows."""
        wanted = self.names if keys is None else [
            k[len(self.PREFIX):] for k in keys if k.startswith(self.PREFIX)]
        found = []
        for name in wanted:
            value = config.value(self.PREFIX + name)
            if value is None:
                continue
            try:
                self._check(name, value)
            except EncodeRangeError as exc:
                found.append(f'{instance}.{self.PREFIX}{name} = {value!r} refused: '
                             f'allowed {exc.allowed}')
            except (TypeError, ValueError) as exc:
                found.append(f'{instance}.{self.PREFIX}{name} = {value!r} refused: {exc}')
        return found

    def complete(self, instance: str, config: DeviceConfig, optional: Iterable[str] = (),
                 hint: str = '') -> dict[str, Any]:
        """Return every set value by field name; RefusedCommand naming all unset ones."""
        skip = set(optional)
        missing = [f'{instance}.{self.PREFIX}{n}' for n in self.names
                   if n not in skip and config.value(self.PREFIX + n) is None]
        if missing:
            raise RefusedCommand(f'{len(missing)} configuration value(s) unset: '
                                 + ', '.join(missing) + (f' ({hint})' if hint else ''))
        return {n: config.value(self.PREFIX + n) for n in self.names
                if config.value(self.PREFIX + n) is not None}
