# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
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
Sections are compared by whether they apply to the node (``section_applies``: rcl's
wildcards ``/**`` and ``/*`` against the node's fully qualified name), not by their
spelling: ``/**:`` with ``commands_allowed: false`` and ``ams_can_bridge:`` (or
``/**/ams_can_bridge:``, ``/*:``) with ``true`` would start the bridge armed.
"""
from __future__ import annotations

import re
from typing import Any

import yaml

from ams_can_bridge.device_set import unknown_parameter_errors
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.input_files import compose_yaml, load_yaml, read_text
from ams_can_bridge.parameters import coerce, ParamSpec, raise_param_errors

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


def section_applies(section: str, fully_qualified_name: str) -> bool:
    """
    Tell whether a params file's top-level key applies to the node, as rcl matches it.

    rcl puts a '/' before a key without one, then reads ``/**`` as any number of name parts
    and ``/*`` (``*``) as exactly one (rclcpp's ``parameter_map_from``; rclpy the same).
    """
    name = section if section.startswith('/') else '/' + section
    pattern = ''
    for part in re.split(r'(/\*\*|\*)', name):
        if part == '/**':
            pattern += '(/[^/]+)*'
        elif part == '*':
            pattern += '[^/]+'
        else:
            pattern += re.escape(part)
    return re.fullmatch(pattern, fully_qualified_name) is not None


def duplicate_problems(path: str, text: str,
                       fully_qualified_name: str | None = None) -> list[str]:
    """
    Return a problem per key given twice and per second section of one node, with lines.

    With the node's ``fully_qualified_name``, a key given in two sections that both apply to
    the node (``/**:`` and ``ams_can_bridge:``) is one too, naming both sections. Raises
    yaml.YAMLError for text that is not YAML (the caller words it), YamlAliasError for any
    alias (rcl takes none in a params file).
    """
    root = compose_yaml(text, f'params file {path}', aliases=False)
    if not isinstance(root, yaml.MappingNode):
        return []
    problems: list[str] = []
    sections: dict[str, tuple[str, int]] = {}
    applying: dict[str, tuple[str, int, str]] = {}  # key -> section, line, value
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
        found: dict[str, tuple[int, str, int]] = {}
        for inner_key, inner in value_node.value:
            if getattr(inner_key, 'value', None) == PARAMETERS_KEY \
                    and isinstance(inner, yaml.MappingNode):
                _flat_names('', inner, f'{name}: {PARAMETERS_KEY}', found, problems, path)
        if fully_qualified_name is None or not section_applies(name, fully_qualified_name):
            continue
        for key, (key_line, value, _) in found.items():
            if key in applying:
                other, other_line, other_value = applying[key]
                problems.append(
                    f'params file {path}: {key} is given in two sections that both apply to '
                    f'the node {fully_qualified_name}: line {other_line} ({other}: {key} = '
                    f'{other_value}) and line {key_line} ({name}: {key} = {value}); rcl '
                    'would take the last one: keep it in one section')
            else:
                applying[key] = (name, key_line, value)
    return problems


def read_params_file(path: str, fully_qualified_name: str | None = None) -> Any:
    """
    Return a parameters file's document; ConfigError for a missing, non-YAML or ambiguous file.

    Ambiguous: a key given twice, a second section for one node, a key given in two sections
    that apply to ``fully_qualified_name`` (``duplicate_problems``).
    """
    text = read_text(path, 'parameters file')
    try:
        problems = duplicate_problems(path, text, fully_qualified_name)
        document = load_yaml(text, f'params file {path}', aliases=False)
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

    Every section that applies to the node ``/<node_name>`` (``/**``, ``/*``, ``name``,
    ``/name``, ``/**/name``) counts, in the file's order, as rcl reads it; a key in two of
    them is refused (``duplicate_problems``). Raises ConfigError for a file that is missing
    or not a parameters file.
    """
    fully_qualified_name = '/' + node_name.lstrip('/')
    document = read_params_file(path, fully_qualified_name)
    if not isinstance(document, dict):
        raise ConfigError(f'parameters file {path!r}: expected "<node name>: ros__parameters:'
                          ' ..." at the top (see config/*.yaml)')
    values: dict[str, Any] = {}
    matched = False
    for key, entry in document.items():
        if not section_applies(str(key), fully_qualified_name):
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
