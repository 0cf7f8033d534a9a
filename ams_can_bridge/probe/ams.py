# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The Formula-Student AMS at any base ID (doc/protocols.md section 1), from its own frames.

Every 11-bit ID whose frames all read as an AMS status (DLC 7, or padded to 8; a known
state, a bank count 0..5, SOC up to 100 %) is a possible base. What makes it an AMS: the
status counter going up by one a frame, and cell / temperature frames at base + 0x011 /
0x012 / 0x013 whose bank/group byte stays inside 5 banks x 4 (cells) or 2 (temperatures)
groups. The bank count is the highest bank whose four cell groups were all heard.
"""
from __future__ import annotations

from typing import Any, Callable

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.probe.evidence import Candidate, stale_setting
from ams_can_bridge.probe.traffic import IdTraffic, Key, Traffic
from ams_can_bridge.protocols import ams as proto
from ams_can_bridge.protocols.ams import AmsCodec

DEFAULT_STALE_S = 0.5  # the device's 5 x 0.1 s
COUNTING = 0.8  # share of status frames whose counter went up by exactly one
SEEN_COUNTING = 3  # status frames from which a counter that never moves rules an AMS out
CELL_V = (1.5, 4.6)  # V: what a lithium cell of an AMS reads (the frame can carry 0..5.1)
# Other AMS frames, claimed when they read as such (a master's and a charger's included)
_OTHERS = {proto.CHARGER_STATUS: 'charger status', proto.CAR_STATUS: 'car status (a master)',
           proto.CHARGER_COMMANDS: 'charger commands (a charger)', proto.ERROR: 'AMS errors',
           proto.OVERRIDE_CHARGE_CURRENT: 'charge current override',
           proto.OVERRIDE_BANK_COUNT: 'bank count override'}


def _decoded(codec: AmsCodec, entry: IdTraffic | None) -> list[Any] | None:
    """Decode every kept payload of an ID; None when one of them is no AMS frame."""
    if entry is None:
        return None
    payloads = entry.payloads + list(entry.by_byte0.values())
    try:
        return [codec.decode(entry.can_id, data) for data in payloads]
    except MalformedFrameError:
        return None


def _groups(readings: list[Any]) -> dict[int, set[int]]:
    banks: dict[int, set[int]] = {}
    for reading in readings:
        banks.setdefault(reading.bank, set()).add(reading.group)
    return banks


def _complete_banks(banks: dict[int, set[int]], groups: int) -> int:
    """Return the highest bank n such that banks 1..n each showed every group."""
    count = 0
    while set(range(groups)) <= banks.get(count + 1, set()):
        count += 1
    return count


def _counter_share(statuses: list[Any]) -> float:
    counters = [s.counter for s in statuses]
    steps = [(b - a) & 0xFF for a, b in zip(counters, counters[1:])]
    return sum(step == 1 for step in steps) / len(steps) if steps else 0.0


def recognise(traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
    """Return one candidate per base ID whose status frames read as an AMS."""
    out = []
    for entry in traffic.of_width(False):
        if not set(entry.dlcs) <= {proto.LAYOUTS[proto.STATUS].length, proto.MAX_DLC}:
            continue
        try:
            codec = AmsCodec(entry.can_id)
        except EncodeRangeError:
            continue  # too high an ID for a base with 0x051 above it
        statuses = _decoded(codec, entry)
        if not statuses:
            continue
        statuses = statuses[:len(entry.samples)]
        if len(statuses) >= SEEN_COUNTING and len({s.counter for s in statuses}) == 1:
            continue  # an AMS counts its status frames
        out.append(_candidate(traffic, codec, entry, statuses))
    return out


def _candidate(traffic: Traffic, codec: AmsCodec, status: IdTraffic,
               statuses: list[Any]) -> Candidate:
    base = codec.base_id
    get: Callable[[int], IdTraffic | None] = lambda offset: traffic.get(base + offset)
    ids: set[Key] = {status.key}
    share = _counter_share(statuses)
    score = 0.3 + (0.25 if share >= COUNTING else 0.0)
    evidence = [f'status 0x{base:03X}: {status.count} frames at {status.rate_hz:.3g} Hz, '
                f'counter +1 in {share:.0%} of them, state {statuses[-1].status.state.name}, '
                f'SOC {statuses[-1].soc_pct} %']
    cand = Candidate('ams', 'ams', f'AMS at base 0x{base:03X}', 0.0, frozenset(), evidence)
    counted = statuses[-1].status.bank_count
    banks = {}
    for offset, groups, what in ((proto.CELL_VOLTAGES, proto.CELL_GROUPS, 'cells'),
                                 (proto.CELL_TEMPERATURES, proto.TEMP_GROUPS, 'temperatures'),
                                 (proto.DISCHARGE_TEMPERATURES, proto.TEMP_GROUPS,
                                  'discharge temperatures')):
        entry = get(offset)
        readings = _decoded(codec, entry)
        if readings and offset == proto.CELL_VOLTAGES and not all(
                CELL_V[0] <= v <= CELL_V[1] for r in readings for v in r.voltages_v):
            readings = None  # bytes that read as cells of 0.3 V or 5 V are something else
        if entry is None or not readings:
            if entry is not None:
                cand.notes.append(f'0x{entry.can_id:03X} does not read as AMS {what}: '
                                  'not counted as part of it')
            continue
        ids.add(entry.key)
        seen = _groups(readings)
        complete = _complete_banks(seen, groups)
        score += 0.3 if offset == proto.CELL_VOLTAGES else 0.05
        text = ', '.join(f'bank {b}: groups {sorted(g)}' for b, g in sorted(seen.items()))
        evidence.append(f'{what} 0x{entry.can_id:03X}: {text}')
        if offset == proto.CELL_VOLTAGES:
            banks = seen
            cand.facts['cell_sum_v'] = sum(
                sum(r.voltages_v) for r in {(r.bank, r.group): r for r in readings}.values())
            cand.facts['cells_complete'] = complete == max(seen)
            if complete and complete == max(seen):
                cand.set('bank_count', complete,
                         f'cell frames of banks 1..{complete}, each with its groups 0..3'
                         + (f' (the status word counts {counted})' if counted else ''))
    padded = max(status.dlcs) == proto.MAX_DLC
    for offset, what in _OTHERS.items():
        entry = get(offset)
        # another sender's frames (the charger's, a master's) come at their own length,
        # unless this AMS pads: 0x351 of an SMA battery is no bank count override
        if entry is not None and (padded or set(entry.dlcs) == {proto.LAYOUTS[offset].length}) \
                and _decoded(codec, entry):
            ids.add(entry.key)
            evidence.append(f'{what} 0x{entry.can_id:03X}: {entry.count} frames')
            if offset == proto.CAR_STATUS:
                cand.notes.append(f'a master already sends the car status 0x{entry.can_id:03X}'
                                  ': keep commands off on this bus (two masters would fight)')
    if cand.setting('bank_count') is None:
        if banks:
            cand.set('bank_count', max(banks), f'check: cell frames of banks {sorted(banks)} '
                     'but not every group of each was heard: listen longer', decided=False)
        elif counted:
            cand.set('bank_count', counted, f'the status word counts {counted} banks (no cell '
                     'frame heard to confirm)')
        else:
            cand.set('bank_count', 1, 'check: no cell frame heard and the status word counts '
                     'no bank: set the number of banks of 28 cells', decided=False)
    if padded:
        evidence.append('frames padded to DLC 8 (accepted, section 1.7)')
    cand.set('base_id', base, f'0x{base:03X}: status there, the other frames at their '
             'offsets from it')
    stale_setting(cand, status.period_s, DEFAULT_STALE_S, 'the status comes')
    cand.set('design_capacity_ah', 20.0, 'check: the AMS does not send its capacity: your '
             "pack's Ah fill BatteryState design_capacity and charge", decided=False)
    cand.confidence = min(score, 1.0)
    cand.ids = frozenset(ids)
    return cand
