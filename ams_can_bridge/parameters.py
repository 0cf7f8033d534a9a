# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Parameters without ROS: the specs of the bus and the node, and the rules every value obeys.

The ROS node declares these specs as parameters (``ros/params.py``); ``log2bag`` reads the
same parameters file without ROS (``params_file.py``). Both check every value here
(``coerce``), so a value is accepted or refused with the same words in both.
"""
from __future__ import annotations

import array
from dataclasses import dataclass
import math
import re
from typing import Any, Iterable

from ams_can_bridge import realtime
from ams_can_bridge.errors import ConfigError, EncodeRangeError, ParamError
from ams_can_bridge.protocols.common import ConfigField
from ams_can_bridge.protocols.layout import check_value

CONFIG_PREFIX = 'config.'
# The most device instances one bridge takes: one CAN bus rarely carries more than a few
# battery devices, and every instance declares ~10 parameters and is checked against every
# other at start. A longer devices list stops the bridge before anything is built.
MAX_DEVICES = 32
MAX_BUS_OPTIONS = 32  # can.options entries (python-can bus arguments)


@dataclass(frozen=True)
class ParamSpec:
    """
    One ROS parameter of a device instance, declared by the node as '<name>.<key>'.

    type is one of bool, int, float, str, 'int[]', 'str[]'. default None = no default
    (declared without a value; the device must cope with it unset). low/high/step give the
    ROS range (FloatingPointRange/IntegerRange); choices restrict strings. max_length: the
    most values an array may have, checked before any element is looked at (a set of
    millions of values is refused at once, never walked, and never holds up a disarm).
    """

    key: str
    type: Any
    default: Any
    description: str
    low: float | None = None
    high: float | None = None
    step: float | None = None
    choices: tuple[str, ...] = ()
    read_only: bool = True
    max_length: int | None = None


def spec_from_config_field(field: ConfigField, key_prefix: str = 'config.',
                           read_only: bool = False) -> ParamSpec:
    """Turn a protocol ConfigField into a ParamSpec with no default (key = prefix + name)."""
    unit = f' [{field.unit}]' if field.unit else ''
    description = (field.description or field.name) + unit
    if field.type == 'int[]' and field.length:
        description += f' ({field.length} values)'
    return ParamSpec(key_prefix + field.name, field.type, None, description, low=field.low,
                     high=field.high, step=field.step, choices=field.choices,
                     read_only=read_only, max_length=field.length or None)


def format_number(value: float, key: str = '') -> str:
    """Format a range bound as a user writes it: CAN IDs in hex, whole numbers exactly."""
    if key.endswith('_id'):  # base_id, command_id, answer_id
        return f'0x{int(value):X}'
    return str(int(value)) if float(value).is_integer() else f'{value:g}'


def allowed_text(spec: ParamSpec) -> str:
    """Describe the values a spec allows, as errors, descriptors and doc/parameters.md say it."""
    parts = []
    if spec.low is not None and spec.high is not None:
        parts.append(f'{format_number(spec.low, spec.key)}..{format_number(spec.high, spec.key)}')
    if spec.step and not (spec.type is int and spec.step == 1):  # whole numbers: implied
        parts.append(f'in steps of {spec.step:g}')
    if spec.choices:
        parts.append('one of ' + ', '.join(c or "''" for c in spec.choices))
    text = ' '.join(parts)
    if spec.max_length is not None:  # an array: its length, then what each value may be
        text = f'at most {spec.max_length} values' + (f', each {text}' if text else '')
    return text


def _check_range(name: str, spec: ParamSpec, value: float) -> None:
    """Check with the package's one validator (protocols.layout.check_value), in its words."""
    if spec.low is None:
        return
    high = math.inf if spec.high is None else spec.high
    for step, what in ((None, 'is out of range'), (spec.step, 'is off the step')):
        if spec.high is None and step is None:
            continue  # no upper bound: only the step from low is a rule
        try:
            check_value(name, value, spec.low, high, step)
        except EncodeRangeError:
            raise ParamError(f'{name} = {value!r} {what}: allowed {allowed_text(spec)}') \
                from None


def numeric_choices(spec: ParamSpec) -> bool:
    """Tell whether a string parameter has choices a user writes as numbers ('0.1')."""
    return spec.type is str and any(_is_number(choice) for choice in spec.choices)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


# '500k', '1M', '250 kbit/s': a rate as people say it, which no parameter reads
_SCALED = re.compile(r'\s*(\d+(?:\.\d+)?)\s*([kKmM])(?:bit|bps|b)?(?:/s)?\s*')


def _suffix_hint(value: Any) -> str:
    """Return ': write 500000' for '500k' (a number with a k or M), else ''."""
    match = _SCALED.fullmatch(value) if isinstance(value, str) else None
    if match is None:
        return ''
    number = float(match.group(1)) * (1e3 if match.group(2) in 'kK' else 1e6)
    return f': write {number:.0f} (the plain number, no k or M)'


def coerce(name: str, spec: ParamSpec, value: Any) -> Any:
    """Return value as spec.type (None stays None = unset) or raise ParamError saying why."""
    if value is None:
        return None
    if spec.type is float or spec.type is int:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(f'{name} = {_short(value)} must be a number'
                             + _suffix_hint(value))
        if spec.type is int:
            if isinstance(value, float) and (not math.isfinite(value) or value != int(value)):
                raise ParamError(f'{name} = {_short(value)} must be a whole number')
            value = int(value)
        else:
            value = float(value)
        _check_range(name, spec, value)
        return value
    if spec.type is bool:
        if not isinstance(value, bool):
            raise ParamError(f'{name} = {_short(value)} must be true or false')
        return value
    if spec.type is str:
        if numeric_choices(spec) and isinstance(value, (int, float)) \
                and not isinstance(value, bool):
            value = f'{value:g}'  # YAML 0.1 for the choice '0.1' (sma.voltage_scale)
        if not isinstance(value, str):
            raise ParamError(f'{name} = {_short(value)} must be a string')
        if spec.choices and value not in spec.choices:
            raise ParamError(f'{name} = {_short(value)} is not allowed: use one of '
                             + ', '.join(c or "''" for c in spec.choices))
        return value
    if spec.type in ('int[]', 'str[]', 'float[]'):
        # rclpy hands integer and float arrays over as array.array (a set through the
        # parameter services, ros2 param set), a params file's values as lists
        if not isinstance(value, (list, tuple, array.array)):
            raise ParamError(f'{name} = {_short(value)} must be a list')
        if spec.max_length is not None and len(value) > spec.max_length:
            # before any per-element work: the length alone refuses it
            raise ParamError(f'{name} has {len(value)} values: at most {spec.max_length} '
                             'are allowed')
        element = {'int[]': int, 'str[]': str, 'float[]': float}[spec.type]
        element_spec = ParamSpec(spec.key, element, None, '', spec.low, spec.high, spec.step,
                                 spec.choices)
        return [coerce(f'{name}[{i}]', element_spec, v) for i, v in enumerate(value)]
    raise ParamError(f'{name}: unsupported parameter type {spec.type!r}')


SHORT_TEXT = 200  # characters of a refused value quoted in its reason
SHORT_ITEMS = 8  # elements of a refused list quoted in its reason


def _short(value: Any) -> str:
    """
    Return repr(value) cut to a readable length, without ever writing out a huge value.

    A refused value may have millions of elements: only a short prefix
    is ever turned into text, so the refusal costs the same whatever its size.
    """
    if isinstance(value, (list, tuple, array.array)) and len(value) > SHORT_ITEMS:
        head = ', '.join(repr(v)[:SHORT_TEXT // SHORT_ITEMS] for v in value[:SHORT_ITEMS])
        return f'[{head}, ...] ({len(value)} values)'
    if isinstance(value, (str, bytes)) and len(value) > SHORT_TEXT:
        return repr(value[:SHORT_TEXT]) + f'... ({len(value)} characters)'
    text = repr(value)
    return text if len(text) <= SHORT_TEXT else text[:SHORT_TEXT] + '...'


def raise_param_errors(errors: list[str]) -> None:
    """Raise one ParamError listing every unusable value given at start, if any."""
    if len(errors) == 1:
        raise ParamError(errors[0])
    if errors:
        raise ParamError(f'{len(errors)} parameters need a change:\n  - '
                         + '\n  - '.join(errors))


def config_param_specs(fields: Iterable[ConfigField]) -> list[ParamSpec]:
    """Return one writable ParamSpec per field, key 'config.<field>', without a default."""
    return [spec_from_config_field(f, CONFIG_PREFIX, read_only=False) for f in fields]


BUS_PARAMS = [
    ParamSpec('interface', str, 'socketcan',
              'python-can interface: socketcan, slcan, pcan, kvaser, virtual, replay, ...'),
    ParamSpec('channel', str, 'can0', 'python-can channel (for replay: the log file)'),
    ParamSpec('bitrate', int, 0, 'bit/s; 0 = leave the adapter as it is', low=0,
              high=10_000_000),
    ParamSpec('fd', bool, False, 'CAN FD bus'),
    ParamSpec('options', 'str[]', [], 'extra python-can bus arguments, key=value (slcan '
              'defaults to timeout=0.5: an idle serial port is not polled every ms)',
              max_length=MAX_BUS_OPTIONS),
    ParamSpec('reconnect_period', float, 1.0, 's between attempts to (re)open the bus',
              low=0.01, high=3600.0),
    ParamSpec('replay_rate', float, 1.0, 'replay speed: 1.0 = real time, 0 = fast as possible',
              low=0.0, high=1000.0),
    ParamSpec('record', str, '', 'file to record the raw bus into (empty = off)'),
    ParamSpec('replay_clock', bool, False,
              'replay only: publish /clock from the log timestamps, so nodes with '
              'use_sim_time follow the recording'),
    ParamSpec('replay_exit', bool, False,
              'replay only: exit (code 0) once the log has been played and its last messages '
              'published; false = keep running, STALE, until stopped'),
    ParamSpec('use_bus_time', bool, False,
              "stamp messages with the interface's receive timestamp (python-can "
              'Message.timestamp; the kernel\'s for SocketCAN) instead of the host clock; '
              'a replay always stamps with the log time'),
    ParamSpec('slcan_bulk_read', bool, True,
              'slcan only: read the serial port in blocks (the bridge\'s reader) instead of '
              "python-can's one byte per system call; false = python-can's own reader"),
    ParamSpec('connect_wait', float, 5.0,
              's a command waits for a bus that is still opening or reconnecting '
              '(0 = fail at once)', low=0.0, high=3600.0),
]
AUTOSTART = ParamSpec(
    'autostart', bool, True, 'lifecycle: configure and activate at start by itself (false: '
    'wait unconfigured for a lifecycle manager, /<node>/change_state)')
NODE_PARAMS = [
    AUTOSTART,
    ParamSpec('devices', 'str[]', [], 'device instance names (each has <name>.type; ROS '
              'names: letters, digits, _, not starting with a digit)',
              max_length=MAX_DEVICES),
    ParamSpec('diagnostics_period', float, 1.0, 's between /diagnostics publications',
              low=0.01, high=3600.0),
    ParamSpec('realtime_priority', int, 0,
              'SCHED_FIFO priority of the bridge\'s own senders (AMS heartbeat, charger '
              'repeat, SMA keep-alive), so a busy computer cannot make their frames late; '
              '0 = the default scheduling. Needs root, CAP_SYS_NICE or an rtprio limit '
              '(doc/real_bus.md); without it the bridge warns and keeps the default',
              low=0, high=realtime.PRIORITY_MAX),
    ParamSpec('commands_allowed', bool, False,
              'first key of the transmit gate, set only at launch: commands_enabled can '
              'become true only while this is true'),
    ParamSpec('commands_enabled', bool, False,
              'transmit gate: false = pure listener, nothing is ever sent; true only with '
              'commands_allowed', read_only=False),
]


def launch_parameters(params_file: str, commands_allowed: str = '',
                      autostart: str = '', examples: str = '') -> list[Any]:
    """
    Return the ``parameters`` of the bridge's launch Node (launch/bridge.launch.py).

    A params file is required: without one the bridge would listen on can0 for no device
    (ConfigError naming params_file and ``examples``, the installed config directory). The
    launch arguments commands_allowed and autostart replace the params file's value only
    when given ('true' / 'false'); left empty (their default), the params file decides.
    """
    if not params_file.strip():
        where = f' in {examples}' if examples else ''
        raise ConfigError('params_file is required: ros2 launch ams_can_bridge bridge.launch.py '
                          'params_file:=/path/to/your.yaml (copy the example for your devices '
                          f'from the config/*.yaml files{where} and set its can.* values)')
    parameters: list[Any] = [params_file]
    given = {}
    for name, value in (('commands_allowed', commands_allowed), ('autostart', autostart)):
        text = value.strip().lower()
        if text not in ('', 'true', 'false'):
            raise ConfigError(f'{name}:={value!r}: use true or false, or leave it out to keep '
                              'the params file value')
        if text:
            given[name] = text == 'true'
    if given:
        parameters.append(given)
    return parameters
