"""
A ROS 2 parameters file read without ROS, for tools that run where rclpy does not.

The file is the one the bridge takes with ``--ros-args --params-file``: node names (or the
wildcards ``/**`` and ``**``) holding ``ros__parameters``, nested mappings joined with dots.
``FileParams.declare`` gives each parameter the file's value or the spec's default, checked by
the same rule as the node (``parameters.coerce``); every unusable value is collected, so the
user sees them all at once (``raise_errors``), as the node reports them, with every key of
the node's sections that nothing declared (a typo), in the node's words.

A key given twice (``commands_allowed: false`` and later ``commands_allowed: true`` in one
section: rcl takes the last, a reader of the top of the file sees the first), or a second
section for the same node, makes the file unusable: ``duplicate_problems`` names the key and
both lines, for log2bag here and for the bridge before it starts (``ros/bridge_main.py``).
"""
from __future__ import annotations

from typing import Any

import yaml

from ams_can_bridge.device_set import unknown_parameter_errors
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.parameters import coerce, ParamSpec, raise_param_errors

WILDCARDS = ('/**', '**')
PARAMETERS_KEY = 'ros__parameters'


def _scalar(node: yaml.Node) -> str:
    """Return how a value node reads in the file (a mapping or a list: shortened)."""
    if isinstance(node, yaml.ScalarNode):
        return str(node.value)
    return '{...}' if isinstance(node, yaml.MappingNode) else '[...]'


def _repeated(where: str, key_nodes: list[tuple[yaml.Node, yaml.Node]],
              problems: list[str], path: str) -> None:
    """Add a problem per key of one mapping given twice."""
    seen: dict[str, tuple[yaml.Node, yaml.Node]] = {}
    for key_node, value_node in key_nodes:
        key = str(key_node.value) if isinstance(key_node, yaml.ScalarNode) else None
        if key is None or key == '<<':
            continue
        if key in seen:
            first_key, first_value = seen[key]
            problems.append(
                f'params file {path}: {where}{key} is given twice, line '
                f'{first_key.start_mark.line + 1} ({_scalar(first_value)}) and line '
                f'{key_node.start_mark.line + 1} ({_scalar(value_node)}); rcl would take the '
                'last one: keep one of them')
        else:
            seen[key] = (key_node, value_node)


def _flat_names(prefix: str, node: yaml.MappingNode, section: str,
                found: dict[str, tuple[int, str, int]], problems: list[str], path: str) -> None:
    """Check one mapping of a section's parameters; nested keys joined with dots as rcl does."""
    _repeated(f'{section}: {prefix}', node.value, problems, path)
    for key_node, value_node in node.value:
        if not isinstance(key_node, yaml.ScalarNode):
            continue
        name = f'{prefix}{key_node.value}'
        if isinstance(value_node, yaml.MappingNode):
            _flat_names(name + '.', value_node, section, found, problems, path)
            continue
        line = key_node.start_mark.line + 1
        first_line, first_value, mapping = found.setdefault(
            name, (line, _scalar(value_node), id(node)))
        if mapping != id(node):  # in one mapping: named by _repeated already
            problems.append(
                f'params file {path}: {section}: {name} is given twice, line {first_line} '
                f'({first_value}) and line {line} ({_scalar(value_node)}), once with dots and '
                'once nested; rcl would take the last one: keep one of them')


def duplicate_problems(path: str, text: str) -> list[str]:
    """
    Return a problem per key given twice and per second section of one node, with lines.

    Raises yaml.YAMLError for text that is not YAML (the caller words it).
    """
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    if not isinstance(root, yaml.MappingNode):
        return []
    problems: list[str] = []
    sections: dict[str, tuple[str, int]] = {}
    for key_node, value_node in root.value:
        if not isinstance(key_node, yaml.ScalarNode):
            continue
        name, line = str(key_node.value), key_node.start_mark.line + 1
        node = name.lstrip('/')  # '/**' is '**', '/ams_can_bridge' is 'ams_can_bridge'
        if node in sections:
            first, first_line = sections[node]
            problems.append(
                f'params file {path}: a second section for the node {first!r}: line '
                f'{first_line} ({first}:) and line {line} ({name}:): merge them into one section')
            continue
        sections[node] = (name, line)
        if not isinstance(value_node, yaml.MappingNode):
            continue
        _repeated(f'{name}: ', value_node.value, problems, path)
        for inner_key, inner in value_node.value:
            if getattr(inner_key, 'value', None) == PARAMETERS_KEY \
                    and isinstance(inner, yaml.MappingNode):
                _flat_names('', inner, f'{name}: {PARAMETERS_KEY}', {}, problems, path)
    return problems


def read_params_file(path: str) -> Any:
    """
    Return a parameters file's document; ConfigError for a missing, non-YAML or ambiguous file.

    Ambiguous: a key given twice or a second section for one node (``duplicate_problems``).
    """
    try:
        with open(path, encoding='utf-8') as stream:
            text = stream.read()
        problems = duplicate_problems(path, text)
        document = yaml.safe_load(text)
    except OSError as exc:
        raise ConfigError(f'parameters file {path!r}: {exc.strerror or exc}') from None
    except yaml.YAMLError as exc:
        raise ConfigError(f'parameters file {path!r} is not valid YAML: {exc}') from None
    if problems:
        raise ConfigError(problems[0] if len(problems) == 1 else
                          f'{len(problems)} problems in params file {path}:\n  - '
                          + '\n  - '.join(problems))
    return document


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
    document = read_params_file(path)
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
