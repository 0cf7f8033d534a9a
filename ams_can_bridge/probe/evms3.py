# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ZEVA EVMS3, its BMS12 modules and TC chargers (doc/protocols.md sections 3 and 7).

The EVMS3 is a status frame in the EVMS3 layout at 4 Hz without the BMS16 marker, 29-bit
unless its firmware was built with 11-bit IDs; its base ID is the status ID. The module
count is the number of BMS12 modules heard (their IDs are fixed, 300 + 10 m + t), the
cells per module the highest cell input of each that read a voltage. TC chargers answer on
0x18FF50E5/E7/E8 and are commanded on 0x1806E5F4/E7F4/E8F4 while the EVMS3 charges.
"""
from __future__ import annotations

from ams_can_bridge.probe import zeva
from ams_can_bridge.probe.evidence import Candidate, sender_proven_elsewhere, stale_setting
from ams_can_bridge.probe.traffic import Key, Traffic
from ams_can_bridge.protocols.bms12 import BMS12_MAX_MODULES
from ams_can_bridge.protocols.evms3 import BATTERY_CURRENT, CONFIG_LAYOUTS, READBACK_IDS
from ams_can_bridge.protocols.tc_charger import COMMAND_IDS, STATUS_IDS

DEFAULT_STALE_S = 1.25  # the device's 5 x 0.25 s
MIN_CELLS = 4  # a BMS12 module has 4..12 cells (section 3.5), or none
# the highest full voltage a 1x build can set (section 3.5): a pack above it needs 2x
MAX_FULL_VOLTAGE_1X = float(next(  # type: ignore[arg-type]  # the row has a range
    s.high for s in CONFIG_LAYOUTS[0].signals if s.name == 'FullVoltage'))


def chargers(traffic: Traffic) -> tuple[set[Key], list[str]]:
    """Return the TC charger IDs heard and what each showed."""
    ids: set[Key] = set()
    evidence = []
    for n, (command, answer) in enumerate(zip(COMMAND_IDS, STATUS_IDS), start=1):
        heard = [traffic.get(i, True) for i in (command, answer)]
        if any(heard):
            ids |= {e.key for e in heard if e is not None}
            pairs = zip(('commands', 'answers'), heard)
            evidence.append(f'TC charger {n}: ' + ', '.join(
                f'{what} {e.label()} ({e.count})' for what, e in pairs if e is not None))
    return ids, evidence


def recognise(traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
    """Return a candidate per ZEVA status without the BMS16 marker; chargers alone too."""
    out = [_candidate(traffic, status) for status in zeva.statuses(traffic) if not status.bms16]
    charger_ids, charger_evidence = chargers(traffic)
    if charger_ids and not out:
        out.append(Candidate(
            'evms3', 'evms3', 'TC chargers without an EVMS3', 0.5, frozenset(charger_ids),
            charger_evidence, writable=False,
            notes=['not written: the bridge reads TC chargers through an evms3 instance, and '
                   'no EVMS3 status was heard']))
    for cand in out:
        if cand.writable and charger_ids:
            cand.ids |= charger_ids
            cand.evidence += charger_evidence
            cand.confidence = min(1.0, cand.confidence + 0.1)
    return out


def _candidate(traffic: Traffic, status: zeva.ZevaStatus) -> Candidate:
    entry = status.entry
    base, extended = entry.can_id, entry.extended
    score = 0.15 + (0.3 if status.four_hz else 0) + (0.1 if extended else 0)
    cand = Candidate('evms3', 'evms3', f'EVMS3 at {entry.label()}', 0.0, frozenset(),
                     [status.describe() + ('' if status.four_hz else ' (an EVMS3 sends 4 Hz)')])
    ids: set[Key] = {entry.key}
    modules = zeva.modules(traffic, extended)
    if modules:
        score += 0.3
        for module in modules:
            ids |= {e.key for e in modules[module][0]}
            ids |= {e.key for e in zeva.module_extras(traffic, module, extended)}
        cand.evidence.append('BMS12 modules ' + ', '.join(
            f'{m}: {count} cells' for m, (_, count) in sorted(modules.items())))
    for can_id, what in ((base + BATTERY_CURRENT, 'battery current'),
                         *((i, 'configuration read-back') for i in READBACK_IDS)):
        heard = traffic.get(can_id, extended)
        if heard is not None and (other := sender_proven_elsewhere(heard)):
            cand.notes.append(f'{heard.label()} not counted as {what}: its frames are '
                              f'{other}')
        elif heard is not None:
            ids.add(heard.key)
            cand.evidence.append(f'{what} {heard.label()}: {heard.count} frames')
    cand.ids = frozenset(ids)
    cand.confidence = min(score, 1.0)
    cand.set('base_id', base, f'{base} (0x{base:X}): the status ID')
    cand.set('extended_id', extended, f'the status comes with a {29 if extended else 11}-bit ID')
    _modules(cand, modules)
    stale_setting(cand, entry.period_s, DEFAULT_STALE_S, 'the status comes')
    _multiplier(cand, max(r.pack_voltage_v for r in status.readings))
    cand.set('config.pack_capacity_ah', 100, 'check: the EVMS3 sends remaining Ah, not the '
             "capacity: your pack's Ah make the SoC (percentage); NaN while unset",
             decided=False)
    return cand


def _multiplier(cand: Candidate, pack_v: float) -> None:
    """Decide the 800 V build from a pack above what a 1x build can set as full (502 V)."""
    if pack_v > MAX_FULL_VOLTAGE_1X:
        cand.set('voltage_multiplier', 2, f'the pack reads {pack_v:g} V, above the '
                 f'{MAX_FULL_VOLTAGE_1X:g} V a 1x build can set as its full voltage: an 800 V '
                 'build (PACK_VOLTAGE_MULTIPLIER 2)')
    else:
        cand.set('voltage_multiplier', 2, f'check: 2 only for an 800 V build of the EVMS3 '
                 f'firmware (PACK_VOLTAGE_MULTIPLIER); the pack reads {pack_v:g} V, which a 1x '
                 'build can serve; no frame tells', decided=False)


def _modules(cand: Candidate, modules: dict[int, tuple[list, int]]) -> None:
    count = max(modules) + 1 if modules else 0
    missing = [m for m in range(count) if m not in modules]
    cand.set('bms12_modules', count,
             (f'BMS12 modules 0..{count - 1} heard' if count else 'no BMS12 module heard')
             + (f' (not module {missing}: its cells stay NaN)' if missing else ''))
    if not count:
        return
    cells = [modules[m][1] if m in modules else 0 for m in range(BMS12_MAX_MODULES)]
    odd = [c for c in cells if c and not MIN_CELLS <= c <= zeva.CELLS_PER_BMS12]
    cand.set('config.cells_per_module', cells,
             ('check: ' if odd else '') + 'the highest cell of each module that read a '
             'voltage' + (f' ({odd}: a BMS12 has 4..12 cells)' if odd else ''),
             decided=not odd)
