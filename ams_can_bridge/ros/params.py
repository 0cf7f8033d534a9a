"""
Declare ParamSpec / ConfigField lists as ROS parameters, and validate values set later.

Numeric parameters are declared with ``dynamic_typing`` so that YAML ``3`` and ``3.0`` (and
``ros2 param set x 3``) both work: rclpy would otherwise refuse an INTEGER for a DOUBLE
parameter. The type and range are then checked here (``coerce``), both at start-up and on
every later set, with a reason that names the parameter, the value and what is allowed.
"""
from __future__ import annotations

import math
from typing import Any, Iterable

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from ams_can_bridge.devices.base import ParamSpec
from ams_can_bridge.protocols.common import ConfigField

_STATIC_TYPES = {
    bool: Parameter.Type.BOOL,
    str: Parameter.Type.STRING,
    'int[]': Parameter.Type.INTEGER_ARRAY,
    'str[]': Parameter.Type.STRING_ARRAY,
    'float[]': Parameter.Type.DOUBLE_ARRAY,
}


class ParamError(ValueError):
    """A parameter value that the bridge cannot use (the message says what to change)."""


def spec_from_config_field(field: ConfigField, key_prefix: str = 'config.',
                           read_only: bool = False) -> ParamSpec:
    """Turn a protocol ConfigField into a ParamSpec with no default (key = prefix + name)."""
    unit = f' [{field.unit}]' if field.unit else ''
    description = (field.description or field.name) + unit
    if field.type == 'int[]' and field.length:
        description += f' ({field.length} values)'
    return ParamSpec(key_prefix + field.name, field.type, None, description, low=field.low,
                     high=field.high, step=field.step, choices=field.choices,
                     read_only=read_only)


def format_number(value: float, key: str = '') -> str:
    """Format a range bound as a user writes it: CAN IDs in hex, whole numbers exactly."""
    if key.endswith('base_id'):
        return f'0x{int(value):X}'
    return str(int(value)) if float(value).is_integer() else f'{value:g}'


def allowed_text(spec: ParamSpec) -> str:
    """Describe the values a spec allows, as error messages, descriptors and README say it."""
    parts = []
    if spec.low is not None and spec.high is not None:
        parts.append(f'{format_number(spec.low, spec.key)}..{format_number(spec.high, spec.key)}')
    if spec.step and not (spec.type is int and spec.step == 1):  # whole numbers: implied
        parts.append(f'in steps of {spec.step:g}')
    if spec.choices:
        parts.append('one of ' + ', '.join(spec.choices))
    return ' '.join(parts)


def _check_range(name: str, spec: ParamSpec, value: float) -> None:
    if spec.low is not None and spec.high is not None:
        if value != value or not spec.low - 1e-9 <= value <= spec.high + 1e-9:
            raise ParamError(f'{name} = {value!r} is out of range: allowed {allowed_text(spec)}')
    if spec.step and spec.low is not None:
        n = (value - spec.low) / spec.step
        if abs(n - round(n)) > 1e-6:
            raise ParamError(f'{name} = {value!r} is off the step: allowed {allowed_text(spec)}')


def coerce(name: str, spec: ParamSpec, value: Any) -> Any:
    """Return value as spec.type (None stays None = unset) or raise ParamError saying why."""
    if value is None:
        return None
    if spec.type is float or spec.type is int:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(f'{name} = {value!r} must be a number')
        if spec.type is int:
            if isinstance(value, float) and (not math.isfinite(value) or value != int(value)):
                raise ParamError(f'{name} = {value!r} must be a whole number')
            value = int(value)
        else:
            value = float(value)
        _check_range(name, spec, value)
        return value
    if spec.type is bool:
        if not isinstance(value, bool):
            raise ParamError(f'{name} = {value!r} must be true or false')
        return value
    if spec.type is str:
        if not isinstance(value, str):
            raise ParamError(f'{name} = {value!r} must be a string')
        if spec.choices and value not in spec.choices:
            raise ParamError(f'{name} = {value!r} is not allowed: use one of '
                             + ', '.join(spec.choices))
        return value
    if spec.type in ('int[]', 'str[]', 'float[]'):
        if not isinstance(value, (list, tuple)):
            raise ParamError(f'{name} = {value!r} must be a list')
        element = {'int[]': int, 'str[]': str, 'float[]': float}[spec.type]
        element_spec = ParamSpec(spec.key, element, None, '', spec.low, spec.high, spec.step,
                                 spec.choices)
        return [coerce(f'{name}[{i}]', element_spec, v) for i, v in enumerate(value)]
    raise ParamError(f'{name}: unsupported parameter type {spec.type!r}')


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """Build the ParameterDescriptor of a spec (description, range, read-only, typing)."""
    desc = ParameterDescriptor(description=spec.description, read_only=spec.read_only)
    constraints = allowed_text(spec)
    if constraints:
        desc.additional_constraints = constraints
    if spec.type in (int, float):
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
        if len(self.errors) == 1:
            raise ParamError(self.errors[0])
        if self.errors:
            raise ParamError(f'{len(self.errors)} parameters need a change:\n  - '
                             + '\n  - '.join(self.errors))

    def declare(self, name: str, spec: ParamSpec) -> Any:
        """
        Declare one parameter; return its coerced value (None = unset).

        Raises ParamError naming the parameter when the value given (override) is unusable.
        """
        self.specs[name] = spec
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


BUS_PARAMS = [
    ParamSpec('interface', str, 'socketcan',
              'python-can interface: socketcan, slcan, pcan, kvaser, virtual, replay, ...'),
    ParamSpec('channel', str, 'can0', 'python-can channel (for replay: the log file)'),
    ParamSpec('bitrate', int, 0, 'bit/s; 0 = leave the adapter as it is', low=0,
              high=10_000_000),
    ParamSpec('fd', bool, False, 'CAN FD bus'),
    ParamSpec('options', 'str[]', [], 'extra python-can bus arguments, key=value'),
    ParamSpec('reconnect_period', float, 1.0, 's between attempts to (re)open the bus',
              low=0.01, high=3600.0),
    ParamSpec('replay_rate', float, 1.0, 'replay speed: 1.0 = real time, 0 = fast as possible',
              low=0.0, high=1000.0),
    ParamSpec('record', str, '', 'file to record the raw bus into (empty = off)'),
]
NODE_PARAMS = [
    ParamSpec('devices', 'str[]', [], 'device instance names (each has <name>.type)'),
    ParamSpec('diagnostics_period', float, 1.0, 's between /diagnostics publications',
              low=0.01, high=3600.0),
    ParamSpec('commands_enabled', bool, False,
              'transmit gate: false = pure listener, nothing is ever sent', read_only=False),
]
