# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The shipped ``dbc`` profiles (foxBMS 2, Orion BMS 2; doc/protocols.md section 8).

Each profile's mapping is looked for as a ``--dbc/--mapping`` pair is (``dbc.match_plan``:
the mapped messages by ID, DLC and DBC range; the primary must be among them). The frames
then go through the dbc device with that profile, as the bridge would read them: the values
it would publish (pack voltage, current, SoC, temperatures, each cell) must be ones a BMS
sends, else the DBC is being read on someone else's frames. A profile's own mark adds
confidence: Orion's checksum byte, the multiplexer values of foxBMS's cell messages (which
also say which cells came, and whether the pack has more than the profile maps).

The other messages of the profile's DBC that were heard are the BMS's too, except those a
device of the bridge explains: foxBMS's DBC describes the IVT-S it reads, whose frames stay
the IVT-S's (a conflict that keeps both). An SMA-family battery reporting the same pack
voltage is the BMS's own SMA-compatible output (Orion's, for an inverter): the profile claims
its IDs, and the conflict keeps the profile, which reads the BMS's own messages.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
import math
from pathlib import Path
from typing import Iterable

from cantools.database.can import Message

from ams_can_bridge.protocols.dbc_mapping.mapping import build_plan
from ams_can_bridge.protocols.dbc_mapping.plan import ARRAY_LABELS, Plan
from ams_can_bridge.protocols.dbc_profiles import profile_files, PROFILES
from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.input_files import read_yaml
from ams_can_bridge.probe.dbc import DEFAULT_STALE_S, match_plan, PlanMatch
from ams_can_bridge.probe.dbc_publish import read_back, say_published, timeouts_setting
from ams_can_bridge.probe.evidence import Candidate, stale_setting, WEAK
from ams_can_bridge.probe.traffic import id_label, IdTraffic, Key, Traffic
from ams_can_bridge.protocols import dbc_codec, orion_bms2
from ams_can_bridge.protocols.dbc_load import read_dbc
from ams_can_bridge.protocols.sma import BATTERY_ID


@dataclass(frozen=True)
class Shipped:
    """What probe says of a profile beyond its files."""

    instance: str  # the instance name it suggests
    title: str
    # IDs whose byte 7 is Orion's checksum (protocols/orion_bms2.py)
    checksum_ids: tuple[int, ...] = ()


SHIPPED = {'foxbms2': Shipped('foxbms2', 'foxBMS 2'),
           'orion_bms2': Shipped('orion', 'Orion BMS 2', orion_bms2.CHECKSUM_IDS)}
SAME_PACK = 0.05  # an SMA voltage within 5 % of the profile's pack voltage is the same pack


@lru_cache(maxsize=None)
def loaded(name: str) -> tuple[Plan, tuple[Message, ...], Path]:
    """Return a profile's plan, its DBC's other messages and its mapping (read once)."""
    dbc_path, mapping_path = profile_files(name)
    dbc = read_dbc(dbc_path)
    plan = build_plan(dbc, read_yaml(mapping_path, 'mapping file'))
    mapped = {(m.frame_id, m.is_extended_id) for m in plan.messages}
    others = tuple(m for m in dbc.db.messages if m.name not in dbc.broken
                   and (m.frame_id, bool(m.is_extended_frame)) not in mapped)
    return plan, others, mapping_path


_COMPILED: dict[int, dbc_codec.CompiledMessage] = {}  # by id() of a message kept in loaded()


def _compiled(message: Message) -> dbc_codec.CompiledMessage:
    """Compile one of the DBC's other messages once, when it is first heard."""
    if id(message) not in _COMPILED:
        _COMPILED[id(message)] = dbc_codec.compile_message(message)
    return _COMPILED[id(message)]


def recognise(traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
    """Return a candidate for each shipped profile whose mapped messages were heard."""
    out = []
    for name in PROFILES:
        plan, others, mapping = loaded(name)
        match = match_plan(traffic, plan)
        if match.ids:
            out.append(_candidate(name, plan, match, traffic, found, others, mapping))
    return out


def _candidate(name: str, plan: Plan, match: PlanMatch, traffic: Traffic,
               found: list[Candidate], others: tuple[Message, ...], mapping: Path) -> Candidate:
    shipped = SHIPPED.get(name, Shipped(name, name))
    cand = Candidate('dbc', shipped.instance, f'{shipped.title}, profile {name}',
                     min(match.score, 0.4), frozenset(match.ids), list(match.evidence))
    primary = plan.messages[plan.primary]
    if not match.primary_heard:
        cand.notes.append(f'not written: its primary message {primary.name} '
                          f'({id_label(primary.frame_id, primary.is_extended_id)}) was not '
                          'heard in range, and the device publishes one BatteryState per frame')
        return cand
    cand.confidence = 0.5 + 0.4 * match.score
    device = read_back({'profile': name}, plan, traffic)
    report = device.battery_report()
    cand.facts['pack_voltage_v'] = report.voltage
    marks = [_checksum(shipped, traffic, cand)] + _arrays(plan, traffic, cand)
    if any(marks):
        cand.confidence = min(1.0, cand.confidence + 0.1)
    say_published(cand, device, report, shipped.title)
    _others(cand, shipped.title, others, traffic, found)
    _same_pack(cand, shipped.title, found)
    cand.set('profile', name, f'{round(match.score * len(plan.messages))} of the '
             f"{len(plan.messages)} messages {name}'s mapping reads heard in range, its "
             f'primary {primary.name} among them')
    stale_setting(cand, match.primary_period_s, DEFAULT_STALE_S, f'{primary.name} comes')
    timeouts_setting(cand, device, traffic)
    _mapping_check(cand, shipped.title, plan, mapping)
    return cand


def _checksum(shipped: Shipped, traffic: Traffic, cand: Candidate) -> bool:
    """Check a checksum byte in every frame of its IDs; True when it holds in all."""
    heard = [e for i in shipped.checksum_ids if (e := traffic.get(i)) is not None]
    frames = [(e.can_id, d) for e in heard for d in e.payloads if len(d) == 8]
    if not frames:
        return False
    right = sum(1 for can_id, d in frames if orion_bms2.checksum_right(can_id, d))
    ids = ', '.join(e.label() for e in heard)
    if right == len(frames):
        cand.evidence.append(f'checksum byte (ID + 8 + bytes 0..6) right in all {right} frames '
                             f'read of {ids}')
        return True
    cand.notes.append(f'checksum byte (ID + 8 + bytes 0..6) right in {right} of {len(frames)} '
                      f'frames of {ids}: a real {shipped.title} sends it right')
    return False


def _runs(values: Iterable[int]) -> str:
    """Write integers as runs: '0..4, 7'."""
    runs: list[list[int]] = []
    for v in sorted(values):
        if runs and v == runs[-1][1] + 1:
            runs[-1][1] = v
        else:
            runs.append([v, v])
    return ', '.join(f'{a}..{b}' if b > a else f'{a}' for a, b in runs)


def _arrays(plan: Plan, traffic: Traffic, cand: Candidate) -> list[bool]:
    """Say which elements the multiplexed array messages carried; True each one heard."""
    marks = []
    for key, array in plan.arrays.items():
        message = plan.messages[array.refs[0].message] if array.refs else None
        if message is None or message.mux_index is None:
            continue
        entry = traffic.get(message.frame_id, message.is_extended_id)
        if entry is None:
            continue
        info = message.signals[message.mux_index]
        heard: set[int] = set()
        for data in {*entry.payloads, *entry.by_byte0.values()}:
            try:
                mux = message.decode(data)[0][message.mux_index]
            except MalformedFrameError:
                continue
            if mux is not None and mux == mux:
                heard.add(round((mux - info.offset) / info.scale))
        mapped = {v for ref in array.refs for v in ref.mux or ()}
        carried = [k for k, ref in enumerate(array.refs) if ref.mux and heard & set(ref.mux)]
        text = (f'{ARRAY_LABELS[key]}: {message.name} {entry.label()} multiplexer values '
                f'{_runs(heard)} heard, carrying elements {_runs(carried) or "none"} of the '
                f'{array.count} mapped')
        if heard - mapped:
            text += (f'; values {_runs(heard - mapped)} carry more than the mapping reads: the '
                     f'pack has more than {array.count}')
            cand.facts.setdefault('beyond', []).append(ARRAY_LABELS[key])
        cand.evidence.append(text)
        marks.append(bool(carried))
    return marks


def _others(cand: Candidate, name: str, others: tuple[Message, ...], traffic: Traffic,
            found: list[Candidate]) -> None:
    """Claim the DBC's other messages heard; leave a bridge device's own to it (a conflict)."""
    claims = {key: c for c in found if c.confidence >= WEAK for key in c.ids}
    own: list[tuple[IdTraffic, str]] = []
    left: dict[int, tuple[Candidate, list[tuple[Key, str]]]] = {}
    for source in others:
        entry = traffic.get(source.frame_id, bool(source.is_extended_frame))
        if entry is None or min(entry.dlcs) < source.length:
            continue
        message = _compiled(source)
        try:
            if any(message.decode(data)[1] for data in entry.payloads):
                continue  # a value outside its range: not this message
        except MalformedFrameError:
            continue
        other = claims.get(entry.key)
        if other is None:
            own.append((entry, source.name))
        else:
            left.setdefault(id(other), (other, []))[1].append((entry.key, source.name))
    if own:
        cand.ids |= {e.key for e, _ in own}
        cand.evidence.append('more of its DBC\'s messages heard in range: ' + ', '.join(
            f'{n} {e.label()}' for e, n in own))
    for other, items in left.values():
        cand.deferred.append((other, frozenset(k for k, _ in items), (
            f'kept both: {other.title} keeps them (the profile\'s DBC names them '
            + ', '.join(n for _, n in items) + f': a device {name} reads), {name} its own '
            'messages')))


def _same_pack(cand: Candidate, name: str, found: list[Candidate]) -> None:
    """Claim an SMA battery's IDs when its 0x356 voltage is the profile's pack voltage."""
    voltage = cand.facts['pack_voltage_v']
    if not (math.isfinite(voltage) and voltage > 0):
        return
    for other in (c for c in found if c.type == 'sma'):
        reading = getattr(other.facts.get('readings', {}).get(BATTERY_ID), 'voltage_v', None)
        if reading is None:
            continue
        for scale, value in ((0.01, reading), (0.1, 10 * reading)):
            if abs(value - voltage) <= SAME_PACK * voltage:
                cand.ids |= other.ids
                cand.evidence.append(
                    f'{other.ids_text()}: the same pack in SMA-family frames (0x356 {value:g} V '
                    f'in {scale:g} V, {name} {voltage:g} V): {name}\'s own SMA-compatible '
                    'output (for an inverter); the profile reads the BMS\'s own messages')
                break


def _mapping_check(cand: Candidate, name: str, plan: Plan, mapping: Path) -> None:
    """Write mapping_file commented out, with what the team must check in the profile."""
    copy = 'then set mapping_file to the copy (the profile keeps its DBC)'
    if 'cell_voltage' not in plan.arrays:
        text = (f'check: the profile maps no cell voltages (only the team knows its cell '
                f'count): to read them, copy {mapping}, add cell_voltage as the comment at '
                f'its top says, {copy}')
    else:
        counts = ' and '.join(f'{a.count} {ARRAY_LABELS[k]}' for k, a in plan.arrays.items())
        beyond = cand.facts.get('beyond')
        text = (f'check: the profile maps {counts} ({name}\'s default pack)'
                + (f', and more {" and ".join(beyond)} were heard' if beyond else '')
                + f': for another pack copy {mapping}, set the counts and the timeouts, {copy}')
    current = plan.scalars.get('current')
    if current is not None and current.ref is not None and current.ref.scale < 0:
        text += (f'. The current is read as {name} counts it by default (discharge positive): '
                 'if yours counts charge positive, drop the scale: -1 in the copy')
    cand.set('mapping_file', f'{cand.name}_mapping.yaml', text, decided=False)
