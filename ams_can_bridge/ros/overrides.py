# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``-p`` values of the command line against those the node received (rcl drops some).

rcl keeps one value per type for a parameter name and hands the node the first of bool,
integer, double, string, arrays: ``-p can.bitrate:=500k`` (a string) beside a params file's
``bitrate: 500000`` is dropped without a word, and so is a ``-p`` given before a
``--params-file`` that sets the same key. The bridge reads its own command line, types each
``-p`` as rcl does and names the ones that did not arrive (a start error: exit 2).
"""
from __future__ import annotations

import array
import math
import re
from typing import Any, Iterable

import yaml

from ams_can_bridge.offline.params_file import section_applies
from ams_can_bridge.ros.params import ros_flag_values

# rcl's reading of a -p value (rcl_yaml_param_parser get_value): these words are booleans,
# then strtoll (base 0: 0x10, 010 octal), then strtod, else a string; quoted: a string.
_RCL_TRUE = frozenset('Y y yes Yes YES true True TRUE on On ON'.split())
_RCL_FALSE = frozenset('N n no No NO false False FALSE off Off OFF'.split())
_RCL_INT = re.compile(r'\s*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)')
_RCL_FLOAT = re.compile(r'\s*[+-]?((\d+\.?\d*|\.\d+)([eE][+-]?\d+)?|inf(inity)?|nan)',
                        re.IGNORECASE)
_RCL_SPECIAL = {'.nan': math.nan, '.inf': math.inf, '+.inf': math.inf, '-.inf': -math.inf}
_KINDS = {bool: ('true or false', 'booleans'), int: ('an integer', 'integers'),
          float: ('a decimal number', 'decimal numbers'), str: ('a string', 'strings')}


def _rcl_scalar(text: str, quoted: bool) -> Any:
    """Return a -p scalar as rcl types it."""
    if quoted:
        return text
    if text in _RCL_TRUE or text in _RCL_FALSE:
        return text in _RCL_TRUE
    match = _RCL_INT.fullmatch(text)
    if match:
        sign, digits = match.groups()
        value = (int(digits[2:], 16) if digits[:2] in ('0x', '0X')
                 else int(digits, 8) if digits.startswith('0') else int(digits))
        value = -value if sign == '-' else value
        if -2 ** 63 <= value < 2 ** 63:  # strtoll: beyond int64 it is read as a double
            return value
    if text.lower() in _RCL_SPECIAL:
        return _RCL_SPECIAL[text.lower()]
    if _RCL_FLOAT.fullmatch(text):
        return float(text)
    return text


def rcl_value(text: str) -> Any:
    """Return the value rcl makes of ``-p name:=<text>`` (a list for ``[a, b]``), or None."""
    items, sequence = [], False
    try:
        for event in yaml.parse(text):
            if isinstance(event, yaml.SequenceStartEvent):
                sequence = True
            elif isinstance(event, yaml.ScalarEvent):
                items.append(_rcl_scalar(event.value, event.style in ("'", '"')
                                         or event.tag == 'tag:yaml.org,2002:str'))
            elif isinstance(event, (yaml.MappingStartEvent, yaml.AliasEvent)):
                return None  # rcl refuses it at init, with its own message
    except yaml.YAMLError:
        return None
    if not sequence and len(items) != 1:
        return None
    return items if sequence else items[0]


def override_rules(argv: Iterable[str]) -> list[tuple[str, str, str]]:
    """Return (node name or '', parameter, value text) of each -p/--param after --ros-args."""
    rules = []
    for rule in ros_flag_values(argv, ('-p', '--param')):
        left, separator, text = rule.partition(':=')
        if separator:
            node, _, name = left.rpartition(':')
            rules.append((node, name, text))
    return rules


def _kind(value: Any) -> str:
    """Name the type of a parameter value as a user writes it ('an integer', 'a list of ...')."""
    if isinstance(value, (list, tuple, array.array)):
        kinds = {_KINDS.get(type(v), ('', type(v).__name__))[1] for v in value}
        return 'a list' + (f' of {kinds.pop()}' if len(kinds) == 1 else '')
    return _KINDS.get(type(value), (type(value).__name__, ''))[0]


def _same(a: Any, b: Any) -> bool:
    """Tell whether two parameter values are equal and of one type (True is not 1)."""
    if isinstance(a, (list, tuple, array.array)) and isinstance(b, (list, tuple, array.array)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if type(a) is not type(b):
        return False
    return bool(a == b) or (isinstance(a, float) and math.isnan(a) and math.isnan(b))


def unapplied_overrides(argv: Iterable[str], fully_qualified_name: str,
                        received: dict[str, Any]) -> list[str]:
    """
    Return an error per ``-p`` of the command line whose value the node did not receive.

    ``received``: the node's parameter overrides (its params files and ``-p`` as rcl merged
    them); a ``-p`` for another node (``other_node:name:=value``) is not the bridge's.
    """
    given: dict[str, list[tuple[str, Any]]] = {}
    for node, name, text in override_rules(argv):
        value = rcl_value(text)
        if value is not None and section_applies(node or '/**', fully_qualified_name):
            given.setdefault(name, []).append((text, value))
    errors = []
    for name, rules in given.items():
        if name not in received or any(_same(value, received[name]) for _, value in rules):
            continue
        text, value = rules[-1]
        got = received[name]
        what = _kind(got)
        if _kind(value) == what:
            errors.append(f'-p {name}:={text} was not applied: the node got {name} = {got!r} '
                          'from a --params-file given after it: put -p after --params-file')
            continue
        example = {'a decimal number': ' (e.g. 2.0, not 2)',
                   'a string': f" (quoted: -p '{name}:=\"{text}\"')"}.get(what, '')
        errors.append(f'-p {name}:={text} was not applied: the node got {name} = {got!r} from '
                      f'the params file, as rcl drops a -p value of another type than the '
                      f"file's ({_kind(value)} here, {what} there) without a word: write it as "
                      f'{what}{example}')
    return errors
