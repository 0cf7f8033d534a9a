"""
A device instance's typed configuration: one frozen dataclass per device type.

The fields come from the device type's ParamSpecs (common, its own, its command services'),
so the parameter list stays the one source of names, types and defaults. A configuration is
built and checked once from parameter values and never changed in place: a parameter change
builds a new one, the device checks it whole and swaps it in with one assignment, so a
reader on another thread sees the old set or the new set, never half of each.

Fields are named as the parameter keys with dots as underscores
(``config.pack_capacity_ah`` -> ``config_pack_capacity_ah``); ``value(key)`` and
``replace({key: value})`` speak parameter keys for the generic code (node, log2bag).
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, ClassVar, Iterable, Mapping, TYPE_CHECKING

from ams_can_bridge.errors import EncodeRangeError, ParamError, RefusedCommand

_PYTHON_TYPES = {'int[]': tuple, 'str[]': tuple, 'float[]': tuple}


def field_name(key: str) -> str:
    """Return the dataclass field of a parameter key ('config.cells' -> 'config_cells')."""
    return key.replace('.', '_')


@dataclasses.dataclass(frozen=True)
class DeviceConfig:
    """Base of the generated configuration classes (see ``make_config_class``)."""

    KEYS: ClassVar[tuple[str, ...]] = ()          # parameter keys, in declaration order
    NO_DEFAULT: ClassVar[frozenset[str]] = frozenset()  # keys that may stay unset (None)

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> DeviceConfig:
        """Build from {parameter key: value}; keys left out take their declared default."""
        unknown = set(values) - set(cls.KEYS)
        if unknown:
            raise ParamError('unknown parameter(s): ' + ', '.join(sorted(unknown)))
        kwargs = {field_name(k): cls._normal(k, v) for k, v in values.items()}
        return cls(**kwargs)

    @classmethod
    def _normal(cls, key: str, value: Any) -> Any:
        if isinstance(value, list):
            # YAML [] cannot be told from unset: a key without default stays unset
            value = None if not value and key in cls.NO_DEFAULT else tuple(value)
        return value

    def value(self, key: str) -> Any:
        """Return the value of a parameter key."""
        return getattr(self, field_name(key))

    if TYPE_CHECKING:
        # The fields are made per device type from its ParamSpecs (make_config_class): the
        # type checker cannot see them, so an attribute read is typed as the value it holds.
        def __getattr__(self, name: str) -> Any:
            """Return a generated field (for the type checker only)."""

    def replace(self, changes: Mapping[str, Any]) -> DeviceConfig:
        """Return a new configuration with these {parameter key: value} changes."""
        unknown = set(changes) - set(self.KEYS)
        if unknown:
            raise ParamError('unknown parameter(s): ' + ', '.join(sorted(unknown)))
        return dataclasses.replace(
            self, **{field_name(k): self._normal(k, v) for k, v in changes.items()})


def make_config_class(type_name: str, specs: Iterable[Any]) -> type[DeviceConfig]:
    """Build the frozen configuration dataclass of a device type from its ParamSpecs."""
    specs = list(specs)
    fields = []
    for spec in specs:
        python_type = _PYTHON_TYPES.get(spec.type, spec.type)
        default = tuple(spec.default) if isinstance(spec.default, list) else spec.default
        fields.append((field_name(spec.key), python_type | None,
                       dataclasses.field(default=default)))
    cls = dataclasses.make_dataclass(
        f'{type_name}Config', fields, bases=(DeviceConfig,), frozen=True,
        namespace={'KEYS': tuple(s.key for s in specs),
                   'NO_DEFAULT': frozenset(s.key for s in specs if s.default is None),
                   '__doc__': f'Typed, frozen configuration of a {type_name} instance.'})
    return cls


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
