"""
Device configuration values as ROS parameters: ``<name>.config.<field>``, no defaults.

The protocol modules list the fields once (``CONFIG_FIELDS``, physical units and wire
ranges) and validate a value (``check_config_value``). This module turns the fields into
ParamSpecs (declared by the node without a value, so "unset" stays detectable), checks every
value with the protocol's own check at start-up and on every later set (out of range, off
step, not an allowed choice: refused with the allowed range), and tells which values are
still missing before a write.
"""
from __future__ import annotations

from typing import Any, Callable, Iterable, Mapping

from ams_can_bridge.protocols.common import ConfigField, EncodeRangeError
from ams_can_bridge.errors import ParamError
from ams_can_bridge.parameters import (  # noqa: F401 (config_param_specs: re-exported)
    CONFIG_PREFIX, config_param_specs)


class ConfigValues:
    """The configuration values of one device instance, as last accepted from parameters."""

    def __init__(self, instance: str, fields: Iterable[ConfigField],
                 check: Callable[[str, Any], Any]) -> None:
        """Keep the fields of one instance; check(field, value) is the protocol's validator."""
        self.instance = instance
        self.fields = tuple(fields)
        self.prefix = f'{instance}.{CONFIG_PREFIX}'
        self._check = check
        self.values: dict[str, Any] = {f.name: None for f in self.fields}

    def field_of(self, full_name: str) -> str | None:
        """Return the field name of a parameter name of this instance (None: not ours)."""
        if not full_name.startswith(self.prefix):
            return None
        name = full_name[len(self.prefix):]
        return name if name in self.values else None

    def reason(self, full_name: str, value: Any) -> str | None:
        """Say why a value cannot be set (None = acceptable, or not a config parameter)."""
        name = self.field_of(full_name)
        if name is None or value is None:
            return None
        try:
            self._check(name, value)
        except EncodeRangeError as exc:
            return f'{full_name} = {value!r} refused: allowed {exc.allowed}'
        except (TypeError, ValueError) as exc:
            return f'{full_name} = {value!r} refused: {exc}'
        return None

    def load(self, params: Mapping[str, Any]) -> None:
        """
        Take the start-up values ({'config.<field>': value}); raise ParamError on bad ones.

        Every bad value is named at once, so a params file is fixed in one go.
        """
        problems = []
        for name in self.values:
            value = params.get(CONFIG_PREFIX + name)
            if isinstance(value, list) and not value:
                value = None  # YAML [] cannot be told from unset: treat it as unset
            why = self.reason(self.prefix + name, value)
            if why:
                problems.append(why)
            self.values[name] = value
        if problems:
            raise ParamError('invalid configuration value(s): ' + '; '.join(problems))

    def update(self, changed: Mapping[str, Any]) -> None:
        """Apply accepted parameter changes ({full_name: value}) of this instance."""
        for full_name, value in changed.items():
            name = self.field_of(full_name)
            if name is not None:
                self.values[name] = None if isinstance(value, list) and not value else value

    def missing(self, optional: Iterable[str] = ()) -> list[str]:
        """Return the full parameter names still unset (fields in optional excepted)."""
        skip = set(optional)
        return [self.prefix + n for n, v in self.values.items() if v is None and n not in skip]

    def as_mapping(self) -> dict[str, Any]:
        """Return every set value by field name (lists as tuples, as the codecs take them)."""
        return {n: tuple(v) if isinstance(v, list) else v
                for n, v in self.values.items() if v is not None}
