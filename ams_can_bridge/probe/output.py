# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The params file probe writes, checked with the bridge's own start-up checks before it is kept.

Every device kept with the settings its evidence decided, each under a comment that gives
the evidence; a setting the evidence cannot decide is written commented out, under a
comment that starts with "check:" and says what to look at. ``commands_allowed: false``:
probe never arms anything. Values are written as the example configs write them (IDs in
decimal with their hex in the comment), so rcl and PyYAML read the same numbers.

``check_file`` reads the file back as ``bridge`` and ``log2bag`` do (the node's entry of a
parameters file, every value through the parameter checks, the device set with its overlap
checks, the bus settings): what it refuses, the bridge would refuse.
"""
from __future__ import annotations

import json
import os
import tempfile
import re
import textwrap
from typing import Any

import yaml

from ams_can_bridge.engine.startup import bus_settings
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.offline.converter import Converter, NODE_NAME
from ams_can_bridge.offline.params_file import FileParams, load_parameters
from ams_can_bridge.parameters import BUS_PARAMS, raise_param_errors
from ams_can_bridge.probe.evidence import Setting
from ams_can_bridge.probe.pack import suggest
from ams_can_bridge.probe.recognise import Findings

WIDTH = 92
_BARE = re.compile(r'[A-Za-z_/][\w./-]*')  # written without quotes when YAML reads it back as is
INDENT = '  '


def scalar(value: Any) -> str:
    """Write a value as YAML that rcl and PyYAML read alike."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(scalar(v) for v in value) + ']'
    if isinstance(value, str):
        if _BARE.fullmatch(value) and yaml.safe_load(value) == value:
            return value
        return json.dumps(value)  # a JSON string is a YAML double-quoted scalar
    return repr(value)


def _comment(text: str, depth: int) -> list[str]:
    pad = INDENT * depth
    return textwrap.wrap(text, WIDTH - len(pad) - 2, initial_indent=pad + '# ',
                         subsequent_indent=pad + '#   ')


def _entries(settings: list[Setting], depth: int) -> list[str]:
    """Write settings, those with a dotted key nested under their first part."""
    lines: list[str] = []
    groups: dict[str, list[Setting]] = {}
    for s in settings:
        head, dot, rest = s.key.partition('.')
        if dot:
            groups.setdefault(head, []).append(Setting(rest, s.value, s.why, s.decided))
            continue
        lines += _comment(s.why, depth)
        line = f'{INDENT * depth}{s.key}: {scalar(s.value)}'
        lines.append(line if s.decided else INDENT * depth + '# ' + line.lstrip())
    for head, members in groups.items():
        inner = _entries(members, depth + 1)
        if any(s.decided for s in members):
            lines.append(f'{INDENT * depth}{head}:')
            lines += inner
        else:  # a header with nothing under it would be a value of its own
            lines.append(f'{INDENT * depth}# {head}:')
            lines += inner
    return lines


def render(findings: Findings, bus: list[Setting], source: str) -> str:
    """Return the params file's text; ``bus``: the can.* settings (keys without 'can.')."""
    devices = findings.written
    lines = [f'# Written by probe from {source}: the devices it recognised on the bus, each',
             '# setting under the evidence that decided it. Lines starting "# check:" need',
             '# you: the setting below them (commented out) is what probe could not decide.',
             '#   bridge --ros-args --params-file <this file>',
             '#   log2bag LOG BAG --params-file <this file>',
             '/**:', '  ros__parameters:']
    depth = 2
    if any(b.decided for b in bus):  # live: an undecided rate is commented out on its own
        lines.append(f'{INDENT * depth}can:')
        lines += _entries(bus, depth + 1)
    else:  # a log: one check for the block
        lines += _comment(' '.join(b.why for b in bus if not b.decided), depth)
        lines.append(f'{INDENT * depth}# can:')
        lines += [f'{INDENT * (depth + 1)}# {b.key}: {scalar(b.value)}' for b in bus]
    lines += _comment('probe never arms the transmit gate: the bridge listens and sends '
                      'nothing until you allow commands at launch and enable them', depth)
    lines += [f'{INDENT * depth}commands_allowed: false',
              f'{INDENT * depth}commands_enabled: false']
    if not devices:
        lines += _comment('no device recognised: see the report of the IDs heard', depth)
    lines.append(f'{INDENT * depth}devices: {scalar([c.name for c in devices])}')
    for cand in devices:
        lines += _comment(f'{cand.title}: confidence {cand.level} ({cand.confidence:.2f})',
                          depth)
        lines.append(f'{INDENT * depth}{cand.name}:')
        lines.append(f'{INDENT * (depth + 1)}type: {cand.type}')
        lines += _entries(cand.settings, depth + 1)
    for cand in findings.devices:
        if not cand.written and cand.writable:
            lines += _comment(f'not written, confidence {cand.level} ({cand.confidence:.2f}): '
                              f'{cand.title}, {cand.ids_text()}', depth)
    pack = suggest(devices, findings.readings)
    if pack is not None:  # commented: whether they form one battery is not on the bus
        lines += _comment(pack.check, depth)
        lines.append(f'{INDENT * depth}# devices: {scalar(pack.devices)}')
        lines += _entries(pack.settings, depth)
    return '\n'.join(lines) + '\n'


def check_file(path: str) -> None:
    """Raise ConfigError with every problem the bridge's start-up checks find in the file."""
    values = load_parameters(path, NODE_NAME)
    params = FileParams(values)
    bus = bus_settings(params.declare_all('can.', BUS_PARAMS))
    raise_param_errors(params.errors + bus.errors)
    Converter(values, None, 'probe')  # every parameter, the device set and its overlaps


def check_target(path: str, inputs: list[str], force: bool) -> None:
    """
    Refuse an output that would destroy something, before probe reads or listens.

    The input log (or a DBC or mapping probe reads) is never replaced, whatever --force
    says, also when reached through another name or a link; a directory is no file name;
    an existing file is replaced only with --force.
    """
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise ConfigError(f'--output {path!r}: the folder {folder!r} does not exist')
    if os.path.isdir(path):
        raise ConfigError(f'--output {path!r} is a directory: give a file name in it, e.g. '
                          f'{os.path.join(path, "params.yaml")!r}')
    if not os.path.lexists(path):
        return
    for given in inputs:
        if os.path.exists(given) and os.path.exists(path) and os.path.samefile(path, given):
            raise ConfigError(f'--output {path!r} is {given!r}, a file probe reads: '
                              'give another name for the params file')
    if not force:
        raise ConfigError(f'--output {path!r} exists: give --force to replace it, or '
                          'another name')
    if not os.path.isfile(path):
        raise ConfigError(f'--output {path!r} exists and is not a regular file: give another '
                          'name')


def write(path: str, text: str) -> None:
    """Write the file only if it passes the start-up checks (ConfigError otherwise)."""
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise ConfigError(f'--output {path!r}: the folder {folder!r} does not exist')
    if os.path.isdir(path):
        raise ConfigError(f'--output {path!r} is a directory: give a file name in it')
    fd, scratch = tempfile.mkstemp(prefix='.probe-', suffix='.yaml', dir=folder)
    try:
        with os.fdopen(fd, 'w', encoding='utf-8') as stream:
            stream.write(text)
        try:
            check_file(scratch)
        except ConfigError as exc:
            raise ConfigError('the params file probe made does not pass the bridge\'s start-up '
                              f'checks (not written; please report it): {exc}') from None
        os.replace(scratch, path)
    finally:
        if os.path.exists(scratch):
            os.unlink(scratch)
