"""
A ROS 2 parameters file read without ROS, for tools that run where rclpy does not.

The file is the one the bridge takes with ``--ros-args --params-file``: node names (or the
wildcards ``/**`` and ``**``) holding ``ros__parameters``, nested mappings joined with dots.
``FileParams.declare`` gives each parameter the file's value or the spec's default, checked by
the same rule as the node (``parameters.coerce``); every unusable value is collected, so the
user sees them all at once (``raise_errors``), as the node reports them, with every key of
the node's sections that nothing declared (a typo), in the node's words.
"""
from __future__ import annotations

from typing import Any

import yaml

from ams_can_bridge.device_set import unknown_parameter_errors
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.parameters import coerce, ParamSpec, raise_param_errors

WILDCARDS = ('/**', '**')


def _flatten(prefix: str, tree: dict, out: dict[str, Any]) -> None:
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            _flatten(name + '.', value, out)
        else:
            out[name] = value


def load_parameters(path: str, node_name: str) -> dict[str, Any]:
    """
    Return the flat parameters the node ``node_name`` gets from a parameters file.

    Wildcard entries apply first, the node's own entries ('name' or '/name') override them,
    as rcl does. Raises ConfigError for a file that is missing or not a parameters file.
    """
    try:
        with open(path, encoding='utf-8') as stream:
            document = yaml.safe_load(stream)
    except OSError as exc:
        raise ConfigError(f'parameters file {path!r}: {exc.strerror or exc}') from None
    except yaml.YAMLError as exc:
        raise ConfigError(f'parameters file {path!r} is not valid YAML: {exc}') from None
    if not isinstance(document, dict):
        raise ConfigError(f'parameters file {path!r}: expected "<node name>: ros__parameters:'
                          ' ..." at the top (see config/*.yaml)')
    values: dict[str, Any] = {}
    matched = False
    for key in (*WILDCARDS, node_name, '/' + node_name):
        entry = document.get(key)
        if entry is None:
            continue
        if not isinstance(entry, dict) or not isinstance(entry.get('ros__parameters'), dict):
            raise ConfigError(f'parameters file {path!r}: {key!r} has no ros__parameters '
                              'mapping')
        _flatten('', entry['ros__parameters'], values)
        matched = True
    if not matched:
        raise ConfigError(f'parameters file {path!r} has no entry for the node {node_name!r}'
                          " (use '/**:' or '" + node_name + ":' at the top)")
    return values


class FileParams:
    """Parameter values from a file, handed out spec by spec like the node declares them."""

    def __init__(self, values: dict[str, Any]) -> None:
        """Keep the file's flat values; nothing is checked until declared."""
        self.values = values
        self.errors: list[str] = []
        self.declared: set[str] = set()

    def declare(self, name: str, spec: ParamSpec) -> Any:
        """Return the value of ``name``: the file's if usable, else the spec's default."""
        self.declared.add(name)
        if name in self.values:
            try:
                value = coerce(name, spec, self.values[name])
            except ParamError as exc:
                self.errors.append(str(exc))
            else:
                return [] if value is None and spec.default == [] else value
        return coerce(name, spec, spec.default)

    def declare_all(self, prefix: str, specs: list[ParamSpec]) -> dict[str, Any]:
        """Declare '<prefix><key>' for every spec; return {key: value}."""
        return {spec.key: self.declare(prefix + spec.key, spec) for spec in specs}

    def raise_errors(self) -> None:
        """Raise one ParamError listing every unusable value and unknown key, if any."""
        raise_param_errors(self.errors + unknown_parameter_errors(self.values, self.declared))
