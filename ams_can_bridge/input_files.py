# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The files the package reads from a user: one check that a path is a regular file, one YAML loader.

``file_problem`` says why a path cannot be read as a file ("does not exist", "is a FIFO, not a
regular file", ...): a FIFO blocks a reader forever, ``/dev/zero`` never ends, a directory
fails deep inside a library, and none of them "does not exist".

``load_yaml`` / ``compose_yaml`` read YAML with ``yaml.SafeLoader`` after counting, from the
parse events alone (no value is built), how many values the document's aliases (``*name``)
stand for once expanded: a "billion laughs" document of a few hundred bytes expands to
billions of values, and PyYAML would build them all. Beyond ``ALIAS_VALUES_LIMIT`` (or any
alias at all where the reader takes none: rcl refuses aliases in params files) the file is
refused, named.

No rclpy and no python-can here: protocol and offline code import this module.
"""
from __future__ import annotations

import os
import stat
from typing import Any

import yaml

from ams_can_bridge.errors import ConfigError

# Values an alias may stand for in one document, all aliases together. A hand-written
# mapping file that reuses a block with ``<<: *common`` a few dozen times stays far below;
# a bomb is over it after its first few levels.
ALIAS_VALUES_LIMIT = 10_000

_KINDS = ((stat.S_ISDIR, 'a directory'), (stat.S_ISFIFO, 'a FIFO (named pipe)'),
          (stat.S_ISCHR, 'a character device'), (stat.S_ISBLK, 'a block device'),
          (stat.S_ISSOCK, 'a socket'))


def file_problem(path: str | os.PathLike[str]) -> str | None:
    """Return why ``path`` cannot be read as a regular file ('does not exist', ...), or None."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return 'does not exist'
    except OSError as exc:
        return f'cannot be read: {exc.strerror or exc}'
    if not stat.S_ISREG(mode):
        kind = next((name for test, name in _KINDS if test(mode)), 'a special file')
        return f'is {kind}, not a regular file'
    if not os.access(path, os.R_OK):
        return 'is not readable'
    return None


class YamlAliasError(ConfigError):
    """A YAML file whose aliases are refused (too many values, a loop, or none allowed)."""


def check_aliases(text: str, where: str, allowed: bool = True) -> None:
    """
    Raise YamlAliasError when the aliases of ``text`` expand beyond the bound (or exist at all).

    ``where`` names the file in the message. Works on parse events, so a bomb costs no more
    than its own length; a YAML syntax error is left to the loader that follows (its message
    has the line).
    """
    sizes: dict[str, int] = {}  # anchor -> values it stands for, once its node is complete
    stack: list[list[Any]] = []  # [anchor, values so far] per open collection
    expanded = 0
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(event, yaml.AliasEvent):
                if not allowed:
                    raise YamlAliasError(
                        f'{where}: YAML aliases (*{event.anchor}, line '
                        f'{event.start_mark.line + 1}) are not allowed here (rcl does not '
                        'take them in a params file): write the values out')
                if event.anchor not in sizes:  # its own node still open: a loop
                    raise YamlAliasError(f'{where}: the YAML alias *{event.anchor} (line '
                                         f'{event.start_mark.line + 1}) refers to itself')
                size = sizes[event.anchor]
                expanded += size
                if expanded > ALIAS_VALUES_LIMIT:
                    raise YamlAliasError(
                        f'{where}: its YAML aliases (*name) stand for more than '
                        f'{ALIAS_VALUES_LIMIT} values once expanded (line '
                        f'{event.start_mark.line + 1}: *{event.anchor}), as an alias bomb '
                        'does: write the values out or reuse fewer')
            elif isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                stack.append([event.anchor, 1])
                continue
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                anchor, size = stack.pop()
                if anchor is not None:
                    sizes[anchor] = size
            elif isinstance(event, yaml.ScalarEvent):
                size = 1
                if event.anchor is not None:
                    sizes[event.anchor] = 1
            else:
                continue
            if stack:
                stack[-1][1] += size
    except yaml.YAMLError:
        return


def load_yaml(text: str, where: str, aliases: bool = True) -> Any:
    """Return the document of ``text`` (SafeLoader), aliases checked; YAMLError if not YAML."""
    check_aliases(text, where, aliases)
    return yaml.load(text, Loader=yaml.SafeLoader)


def compose_yaml(text: str, where: str, aliases: bool = True) -> yaml.Node | None:
    """Return the node tree of ``text`` (SafeLoader), aliases checked first, as load_yaml."""
    check_aliases(text, where, aliases)
    return yaml.compose(text, Loader=yaml.SafeLoader)


def read_text(path: str | os.PathLike[str], what: str) -> str:
    """Return a user's text file; ConfigError naming ``what`` and the path when it cannot be."""
    where = f'{what} {str(path)!r}'
    problem = file_problem(path)
    if problem:
        raise ConfigError(f'{where} {problem}')
    try:
        with open(path, encoding='utf-8') as stream:
            return stream.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f'{where} cannot be read: {getattr(exc, "strerror", None) or exc}') \
            from None


def read_yaml(path: str | os.PathLike[str], what: str, aliases: bool = True) -> Any:
    """
    Read and load a YAML file; ConfigError naming ``what`` and the path when it cannot be.

    A file that is not YAML raises yaml.YAMLError (the caller words it with the line).
    """
    return load_yaml(read_text(path, what), f'{what} {str(path)!r}', aliases)
