# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A team's DBC as the field has it: loaded whole when cantools can, else what can be used.

cantools refuses a whole file for one bad message with ``strict=True`` (overlapping signals,
a signal that does not fit its message; duplicated signal names read as overlapping), and
even without strict for some lines (unused ``VAL_`` entries, a standard ID over 11 bits, a
line it cannot parse). ``read_dbc`` loads strictly first. Failing that, it loads without
strict, blanking each line cantools still refuses (a message's whole block when the line is
its ``BO_``: its ``SG_`` lines would otherwise join the message before it), and then checks
every message as strict would, duplicated names told apart (``Blank#1``, ``Blank#2``): each
broken message is named with its reason, the others work. doc/protocols.md section 8.
"""
from __future__ import annotations

import contextlib
import logging
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import cantools
from cantools.database.can import Database, Message

# a line cantools cannot take is blanked and the file read again; a file needing more is
# not a DBC worth guessing at
MAX_DROPPED = 200
DUPLICATE_MARK = '#'  # Blank, Blank -> Blank#1, Blank#2 (no DBC name may hold a '#')
# The Orion BMS utility exports a message's period only as a comment
ORION_PERIOD = re.compile(r'Transmits at (\d+(?:\.\d+)?) ms', re.IGNORECASE)
# CANdb++ keeps signals that are in no message in a placeholder message of this name (ID
# 0xC0000000, DLC 0); cantools leaves it out, and its value tables with it.
PLACEHOLDER = 'VECTOR__INDEPENDENT_SIG_MSG'
_PLACEHOLDER_BO = re.compile(r'^\s*BO_\s+(\d+)\s+' + PLACEHOLDER + r'\s*:', re.MULTILINE)
# A DBC's text: UTF-8 as most tools write it now (the IVT-S vendor DBC's "°C"), else cp1252
# as CANdb++ writes it, else latin-1 (which reads any byte).
ENCODINGS = ('utf-8-sig', 'cp1252', 'latin-1')

_SYNTAX = re.compile(r'Invalid syntax at line (\d+), column \d+')
_UNUSED_VAL = re.compile(r'^\s*VAL_ (\d+) (\S+)\s*$', re.MULTILINE)
_BAD_ID = re.compile(r'frame id 0x[0-9a-fA-F]+ is more than \d+ bits in message (\S+?)\.')


class DbcLoadError(ValueError):
    """The file cannot be read as a DBC at all (the reason, in cantools' words)."""


@dataclass
class LoadedDbc:
    """A database and what had to be left out of it to load it."""

    db: Database
    strict: bool  # cantools took the file as it is with strict=True
    dropped: list[str] = field(default_factory=list)  # 'line N (reason): text'
    broken: dict[str, str] = field(default_factory=dict)  # message name -> why unusable
    duplicates: dict[str, dict[str, int]] = field(default_factory=dict)  # msg -> {name: n}
    info: list[str] = field(default_factory=list)  # said once at start (INFO), not a fault

    def notes(self) -> list[str]:
        """Say, one line each, what was dropped and which messages are broken (WARN)."""
        out = [f'DBC {text}' for text in self.dropped]
        out += [f'DBC message {name} is broken and unusable: {why}'
                for name, why in sorted(self.broken.items())]
        for name, names in sorted(self.duplicates.items()):
            listed = ', '.join(f'{n} (x{count})' for n, count in sorted(names.items()))
            out.append(f'DBC message {name} has duplicated signal names {listed}: those '
                       'signals cannot be mapped (rename them in the DBC); the others can')
        return out


def read_dbc(path: str | Path) -> LoadedDbc:
    """Load a DBC file (UTF-8, else cp1252 as CANdb++ writes); DbcLoadError when nothing loads."""
    data = Path(path).read_bytes()
    text, encoding = _decode(data)
    text, info = _without_placeholder(text)
    if not data.isascii():  # where it matters: units such as °C, texts in comments
        info.insert(0, f'DBC read as {encoding}')
    try:
        with _quiet_cantools():
            db = cantools.database.load_string(text, database_format='dbc', strict=True)
    except cantools.database.Error:
        pass
    else:
        loaded = LoadedDbc(db, strict=True, info=info)  # type: ignore[arg-type]  # CAN db
        _check_messages(loaded)  # duplicate definitions load even strictly
        return loaded
    lines = text.splitlines()
    dropped: list[str] = []
    for _ in range(MAX_DROPPED):
        try:
            with _quiet_cantools():
                db = cantools.database.load_string('\n'.join(lines), database_format='dbc',
                                                   strict=False)
            break
        except cantools.database.Error as exc:
            reason = str(exc).removeprefix('DBC: ').strip('"')
            found, why = _offending(reason, lines)
            if not found:
                raise DbcLoadError(f'cantools cannot read it: {reason}') from None
            block = len(found) > 1 and lines[found[0]].lstrip().startswith('BO_ ')
            for i in found[:1] if block else found:
                dropped.append(f'line {i + 1} dropped ({why}): {lines[i].strip()}'
                               + (f' with its {len(found) - 1} SG_ line(s)' if block else ''))
            for i in found:
                lines[i] = ''
    else:
        raise DbcLoadError(f'more than {MAX_DROPPED} lines cantools cannot read')
    loaded = LoadedDbc(db, strict=False, dropped=dropped,  # type: ignore[arg-type]
                       info=info)
    _check_messages(loaded)
    return loaded


@contextlib.contextmanager
def _quiet_cantools() -> Iterator[None]:
    """Keep cantools' own warnings (duplicate definitions) off stderr: notes() says them."""
    logger = logging.getLogger('cantools')
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def _decode(data: bytes) -> tuple[str, str]:
    """Return the file's text and the encoding it was read in (the first of ENCODINGS)."""
    *strict, last = ENCODINGS
    for encoding in strict:
        try:
            return data.decode(encoding), encoding.removesuffix('-sig').upper()
        except UnicodeDecodeError:
            continue
    return data.decode(last), last.upper()  # latin-1 reads any byte


def _without_placeholder(text: str) -> tuple[str, list[str]]:
    """
    Leave out the value tables of CANdb++'s placeholder message, and say so (INFO).

    Its signals are in no message, so no frame carries them; cantools drops the message and
    then refuses its value tables as "unused VAL_ entries" (a whole CANdb++ export would
    otherwise fail the strict load, and every table be named as a table of no signal).
    """
    match = _PLACEHOLDER_BO.search(text)
    if match is None:
        return text, []
    ident = match.group(1)
    kept, tables = [], 0
    for line in text.splitlines():
        words = line.split(None, 2)
        if len(words) > 1 and words[0] in ('VAL_', 'SIG_VALTYPE_') and words[1] == ident:
            tables += 1
            line = ''  # blanked, not removed: the line numbers other notes give stay true
        kept.append(line)
    if not tables:  # cantools leaves the message out quietly: nothing to say
        return text, []
    return '\n'.join(kept), [
        f"DBC: CANdb++'s placeholder message {PLACEHOLDER} (ID {ident}: signals in no "
        f'message, never on the bus) left out with its {tables} value table(s)']


def _offending(reason: str, lines: list[str]) -> tuple[list[int], str]:
    """Return the indices of the lines cantools' error names (a BO_ with its SG_ lines)."""
    match = _SYNTAX.search(reason)
    if match:
        i = int(match.group(1)) - 1
        return (_block(lines, i) if 0 <= i < len(lines) else []), 'cantools cannot parse it'
    if reason.startswith('unused VAL_ entries'):
        wanted = set(_UNUSED_VAL.findall(reason))
        return [i for i, line in enumerate(lines) if line.lstrip().startswith('VAL_ ')
                and tuple(line.split()[1:3]) in wanted], 'value table of no signal'
    match = _BAD_ID.search(reason)
    if match:
        name = match.group(1)
        for i, line in enumerate(lines):
            words = line.split()
            if len(words) > 2 and words[0] == 'BO_' and words[2].rstrip(':') == name:
                return _block(lines, i), f'message {name}: a standard ID over 11 bits'
    return [], ''


def _block(lines: list[str], i: int) -> list[int]:
    """Return line i, and when it is a BO_ line the SG_ lines that belong to it."""
    found = [i]
    if lines[i].lstrip().startswith('BO_ '):
        for k in range(i + 1, len(lines)):
            stripped = lines[k].strip()
            if stripped.startswith('SG_ '):
                found.append(k)
            elif stripped:
                break
    return found


def _check_messages(loaded: LoadedDbc) -> None:
    """Find each broken message as cantools' strict check would, and the duplicates."""
    messages = loaded.db.messages
    defined = Counter((m.frame_id, bool(m.is_extended_frame)) for m in messages)
    named = Counter(m.name for m in messages)
    for message in messages:
        count = max(named[message.name], defined[(message.frame_id,
                                                  bool(message.is_extended_frame))])
        if count > 1:
            loaded.broken[message.name] = (
                f'defined {count} times (the same name or CAN ID 0x{message.frame_id:X}); '
                'cantools keeps only the last definition')
            continue
        names = Counter(s.name for s in message.signals)
        duplicated = {n: c for n, c in names.items() if c > 1}
        if duplicated:
            loaded.duplicates[message.name] = duplicated
            seen: Counter[str] = Counter()
            for signal in message.signals:
                if signal.name in duplicated:
                    seen[signal.name] += 1
                    signal.name = f'{signal.name}{DUPLICATE_MARK}{seen[signal.name]}'
        try:
            message.refresh(strict=True)
        except cantools.database.Error as exc:
            loaded.broken[message.name] = str(exc).replace(
                f' in message {message.name}', '').rstrip('.')
            message.refresh(strict=False)


def cycle_time(message: Message) -> tuple[float | None, str]:
    """
    Return the message's period in s and where it came from (None: the DBC does not say).

    ``GenMsgCycleTime`` (ms, 0 = not periodic), else the Orion utility's comment "This ID
    Transmits at N ms.".
    """
    if message.cycle_time:
        return message.cycle_time / 1000.0, f'GenMsgCycleTime {message.cycle_time} ms'
    match = ORION_PERIOD.search(message.comment or '')
    if match:
        return float(match.group(1)) / 1000.0, f'comment "Transmits at {match.group(1)} ms"'
    return None, ''
