# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Declare ParamSpec / ConfigField lists as ROS parameters, and validate values set later.

Numeric parameters are declared with ``dynamic_typing`` so that YAML ``3`` and ``3.0`` (and
``ros2 param set x 3``) both work: rclpy would otherwise refuse an INTEGER for a DOUBLE
parameter. So is a string parameter with number choices (``voltage_scale: 0.1``). The type
and range are then checked here (``coerce``), both at start-up and on every later set, with
a reason that names the parameter, the value and what is allowed.
"""
from __future__ import annotations

from typing import Any, Iterable

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter
import yaml

from ams_can_bridge.device_set import unknown_parameter_errors
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.input_files import load_yaml
from ams_can_bridge.offline.params_file import duplicate_problems, section_applies
from ams_can_bridge.parameters import (
    allowed_text, coerce, numeric_choices, ParamSpec, raise_param_errors)

_STATIC_TYPES = {
    bool: Parameter.Type.BOOL,
    str: Parameter.Type.STRING,
    'int[]': Parameter.Type.INTEGER_ARRAY,
    'str[]': Parameter.Type.STRING_ARRAY,
    'float[]': Parameter.Type.DOUBLE_ARRAY,
}


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """Build the ParameterDescriptor of a spec (description, range, read-only, typing)."""
    desc = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    constraints = allowed_text(spec)
    if constraints:
        desc.additional_constraints = constraints
    if spec.type in (int, float) or numeric_choices(spec):
        desc.dynamic_typing = True  # see module docstring: 3 and 3.0 both work
        if spec.low is not None and spec.high is not None:
            if spec.type is int:
                desc.integer_range = [IntegerRange(from_value=int(spec.low),
                                                   to_value=int(spec.high),
                                                   step=int(spec.step or 0))]
            else:
                desc.floating_point_range = [FloatingPointRange(
                    from_value=float(spec.low), to_value=float(spec.high),
                    step=float(spec.step or 0.0))]
    return desc


class ParamRegistry:
    """Every parameter the node declared from specs, so later sets can be validated."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.specs: dict[str, ParamSpec] = {}
        self.last_reason = ''  # of the last refused value (rclpy wraps it in its exception)
        self.errors: list[str] = []  # unusable values given at start, all of them

    def raise_errors(self) -> None:
        """Raise one ParamError listing every unusable start value, if there was any."""
        raise_param_errors(self.errors)

    def declare(self, name: str, spec: ParamSpec) -> Any:
        """
        Declare one parameter; return its coerced value (None = unset).

        Raises ParamError naming the parameter when the value given (override) is unusable.
        """
        self.specs[name] = spec
        if self.node.has_parameter(name):  # configured again (lifecycle): as it stands
            try:
                value = self.node.get_parameter(name).value
            except ParameterUninitializedException:  # declared unset: no value given
                value = None
            value = coerce(name, spec, value)
            return [] if value is None and spec.default == [] else value
        desc = descriptor(spec)
        # Check the value from the params file / overrides with our own rules first, so the
        # user gets our message, and every bad value at once (rclpy stops at the first).
        ignore = False
        override = self.node._parameter_overrides.get(name)  # rclpy has no public getter
        if override is not None and override.type_ != Parameter.Type.NOT_SET:
            try:
                coerce(name, spec, override.value)
            except ParamError as exc:
                self.errors.append(str(exc))
                ignore = True  # declare with the default; raise_errors() reports it
        try:
            if spec.type in (int, float):
                default = None if spec.default is None else spec.type(spec.default)
                param = self.node.declare_parameter(name, default, desc, ignore)
            elif spec.default is None or spec.default == []:
                # an empty list cannot carry its element type, and YAML [] arrives unset
                param = self.node.declare_parameter(
                    name, _STATIC_TYPES[spec.type], desc, ignore)
            else:
                param = self.node.declare_parameter(name, spec.default, desc, ignore)
        except ParamError:
            raise
        except Exception as exc:  # rclpy's type/range exceptions: reword for the user
            reason = self.last_reason if self.last_reason.startswith(name) else str(exc)
            raise ParamError(reason if reason.startswith(name) else f'{name}: {reason}') \
                from None
        value = coerce(name, spec, param.value)
        if value is None and spec.type in ('int[]', 'str[]', 'float[]') and spec.default == []:
            return []
        return value

    def declare_all(self, prefix: str, specs: Iterable[ParamSpec]) -> dict[str, Any]:
        """Declare '<prefix><key>' for every spec; return {key: value}."""
        return {spec.key: self.declare(prefix + spec.key, spec) for spec in specs}

    def validate(self, param: Parameter) -> str | None:
        """Reason string when param's new value is unusable, None when fine or not ours."""
        spec = self.specs.get(param.name)
        if spec is None:
            return None
        try:
            coerce(param.name, spec, param.value)
        except ParamError as exc:
            self.last_reason = str(exc)
            return self.last_reason
        return None

    def value(self, param: Parameter) -> Any:
        """Return the coerced value of a parameter that passed validate()."""
        spec = self.specs.get(param.name)
        return param.value if spec is None else coerce(param.name, spec, param.value)

    def unknown(self) -> list[str]:
        """Return a message per key given for the node (file, -p) that nothing declared."""
        given = {name: p.value for name, p in self.node._parameter_overrides.items()}
        return unknown_parameter_errors(given, self.node._parameters.keys())


def ros_flag_values(argv: Iterable[str], flags: tuple[str, ...]) -> list[str]:
    """Return the argument after each of ``flags`` in the ``--ros-args`` parts of argv."""
    values, ros, args = [], False, list(argv)
    for i, arg in enumerate(args):
        if arg == '--ros-args':
            ros = True
        elif arg == '--':
            ros = False
        elif ros and arg in flags and i + 1 < len(args):
            values.append(args[i + 1])
    return values


def params_files(argv: Iterable[str]) -> list[str]:
    """Return the ``--params-file`` paths of the ``--ros-args`` parts of a command line."""
    return ros_flag_values(argv, ('--params-file',))


def node_name_from_argv(argv: Iterable[str], node_name: str) -> str:
    """
    Return the fully qualified name a node called ``node_name`` gets from the command line.

    Read from the ``-r``/``--remap`` rules ``__node:=`` (``__name:=``) and ``__ns:=``, a rule
    prefixed ``<node>:`` only for that node, as rcl applies them (the last one wins).
    """
    name, namespace = node_name, '/'
    for rule in ros_flag_values(argv, ('-r', '--remap')):
        left, separator, value = rule.partition(':=')
        prefix, _, key = left.rpartition(':')
        if not separator or prefix not in ('', node_name):
            continue
        if key in ('__node', '__name'):
            name = value
        elif key == '__ns':
            namespace = value if value.startswith('/') else '/' + value
    return namespace.rstrip('/') + '/' + name


def params_file_problems(argv: Iterable[str], fully_qualified_name: str) -> list[str]:
    """
    Return why the params files of a command line cannot be used as written ([] = fine).

    rcl takes the last of a key given twice (``commands_allowed: false`` at the top, ``true``
    further down or in another section that applies to the node starts the bridge armed):
    such a key, or a second section for the node, stops the bridge before it is built,
    naming the key, both lines and both sections.
    """
    problems = []
    for path in params_files(argv):
        try:
            with open(path, encoding='utf-8') as stream:
                problems += duplicate_problems(path, stream.read(), fully_qualified_name)
        except (OSError, yaml.YAMLError, ConfigError):
            continue  # rcl has refused it already, with its own message
    return problems


def unmatched_params_files(argv: Iterable[str], fully_qualified_name: str) -> list[str]:
    """
    Return a warning per params file of the command line that has no section for the node.

    rcl silently ignores the sections of other nodes: a file keyed ``ams_can_bridge:`` given
    to a bridge started in a namespace (``-r __ns:=/car2``) configures nothing.
    """
    warnings = []
    for path in params_files(argv):
        try:
            with open(path, encoding='utf-8') as stream:
                document = load_yaml(stream.read(), f'params file {path}', aliases=False)
        except (OSError, yaml.YAMLError, ConfigError):
            continue  # rcl has refused it already, with its own message
        if not isinstance(document, dict):
            continue
        sections = [str(key) for key in document]
        if any(section_applies(key, fully_qualified_name) for key in sections):
            continue
        warnings.append(
            f'params file {path}: no section applies to this node {fully_qualified_name} '
            f'(its sections: {", ".join(sections) or "none"}), so none of its values is '
            f'used. Key it {fully_qualified_name}: or /**: (any node name and namespace), '
            'or start the node with the name and namespace the file names')
    return warnings
