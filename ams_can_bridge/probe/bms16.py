# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ZEVA BMS16 in both its forms (doc/protocols.md sections 4 and 6).

Inverter form (11-bit): a status frame of DLC 7 (error code 0..8, SoC up to 100 %) at any
base, its cells at base + 1..3 (DLC 7, 9-bit 0.01 V), 4 Hz, and usually the SMA frames
0x351.. beside them (which it then explains: an sma instance would show the same pack
again). Standard form (29-bit, the EVMS3 protocol): the ZEVA status with byte 5 = 255, its
cells as BMS12 modules 0 and 1 (8 cells on module 0, the rest on module 1), the current on ID
40. The cell count is the highest cell that read a voltage.
"""
from __future__ import annotations

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.probe import zeva
from ams_can_bridge.probe.evidence import Candidate, stale_setting
from ams_can_bridge.probe.traffic import IdTraffic, Key, Traffic
from ams_can_bridge.protocols import bms16 as inverter
from ams_can_bridge.protocols.bms16 import Bms16Cells, Bms16Codec, Bms16Status
from ams_can_bridge.protocols.bms16_std import (
    CAN_CURRENT_SENSOR_ID, CELLS_PER_MODULE, MAX_CELLS)
from ams_can_bridge.protocols.sma import SMA_IDS

DEFAULT_STALE_S = 1.25  # both forms: 5 x 0.25 s
CELL_RANGE = {'inverter': (12, 16), 'standard': (8, 16)}  # config.cells of each form


def recognise(traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
    """Return a candidate per status frame of either form."""
    out = []
    for entry in traffic.of_width(False):
        if set(entry.dlcs) == {inverter.LAYOUTS[inverter.STATUS].length}:
            cand = _inverter(traffic, entry)
            if cand is not None:
                out.append(cand)
    out += [_standard(traffic, status) for status in zeva.statuses(traffic) if status.bms16]
    return out


def _inverter(traffic: Traffic, status: IdTraffic) -> Candidate | None:
    base = status.can_id
    try:
        codec = Bms16Codec(base)
        readings = [r for data in status.payloads
                    if isinstance(r := codec.decode(base, data), Bms16Status)]
    except (EncodeRangeError, MalformedFrameError):
        return None
    if not readings:
        return None
    ids: set[Key] = {status.key}
    last = readings[-1]
    four_hz = zeva.FOUR_HZ[0] <= status.period_s <= zeva.FOUR_HZ[1]
    cand = Candidate('bms16', 'bms16', f'BMS16 (inverter form) at 0x{base:03X}', 0.0,
                     frozenset(), [f'status 0x{base:03X} ({base}): {status.count} frames every '
                                   f'{status.period_s * 1000:.0f} ms, SoC {last.soc_pct} %, '
                                   f'{last.voltage_v:g} V, error {last.error.name}'])
    score = 0.3 + (0.2 if four_hz else 0)
    count = 0
    for offset in (inverter.CELLS_1, inverter.CELLS_2, inverter.CELLS_3):
        entry = traffic.get(base + offset)
        if entry is None:
            continue
        try:
            cells = [codec.decode(entry.can_id, data) for data in entry.payloads]
        except MalformedFrameError:
            continue
        ids.add(entry.key)
        count = max([count] + [_highest(c) for c in cells if isinstance(c, Bms16Cells)])
    if count:
        score += 0.3
        cand.evidence.append(f'cells at 0x{base + 1:03X}..0x{base + 3:03X}: {count} read a '
                             'voltage')
    sma = {e.key for i in SMA_IDS if (e := traffic.get(i)) is not None}
    if sma and count:
        ids |= sma
        score += 0.2
        cand.evidence.append('the SMA frames ' + ', '.join(f'0x{i:03X}' for i, _ in sorted(sma))
                             + ' beside them, as a BMS16 sends them (section 4): read by this '
                             'instance, no sma instance needed')
    cand.ids = frozenset(ids)
    cand.confidence = min(score, 1.0)
    cand.set('base_id', base, f'{base} (0x{base:03X}): the status ID, cells after it')
    _cells(cand, count, 'inverter')
    stale_setting(cand, status.period_s, DEFAULT_STALE_S, 'the status comes')
    return cand


def _highest(cells: Bms16Cells) -> int:
    lit = [k for k, v in enumerate(cells.voltages_v) if v >= zeva.NO_CELL_V]
    return cells.first_cell + max(lit) + 1 if lit else 0


def _standard(traffic: Traffic, status: zeva.ZevaStatus) -> Candidate:
    entry = status.entry
    cand = Candidate('bms16', 'bms16', f'BMS16 (standard form) at {entry.label()}', 0.0,
                     frozenset(), [status.describe() + ', byte 5 = 255 (the BMS16 marker)'])
    score = 0.5 + (0.2 if status.four_hz else 0)
    ids: set[Key] = {entry.key}
    modules = {m: found for m in (0, 1)
               if (found := zeva.module_cells(traffic, m, entry.extended)) is not None}
    for frames, _ in modules.values():
        ids |= {e.key for e in frames}
    count = 0
    if modules:
        score += 0.3
        first = modules[0][1] if 0 in modules else 0
        count = (CELLS_PER_MODULE + modules[1][1]) if 1 in modules else first
        cand.evidence.append('cells as BMS12 modules ' + ', '.join(
            f'{m}: {n}' for m, (_, n) in sorted(modules.items())))
    current = traffic.get(CAN_CURRENT_SENSOR_ID, entry.extended)
    if current is not None and set(current.dlcs) == {3}:
        ids.add(current.key)
        cand.evidence.append(f'current {current.label()}: {current.count} frames (a shunt)')
    cand.ids = frozenset(ids)
    cand.confidence = min(score, 1.0)
    cand.set('variant', 'standard', 'the ZEVA status with the BMS16 marker (section 6)')
    cand.set('base_id', entry.can_id, f'{entry.can_id}: the status ID')
    _cells(cand, count, 'standard')
    stale_setting(cand, entry.period_s, DEFAULT_STALE_S, 'the status comes')
    return cand


def _cells(cand: Candidate, count: int, form: str) -> None:
    low, high = CELL_RANGE[form]
    if low <= count <= high:
        cand.set('config.cells', count, f'{count} cells read a voltage (sizes cell_voltage)')
    else:
        cand.set('config.cells', MAX_CELLS, f'check: {count} cells read a voltage, a BMS16 '
                 f'of this form has {low}..{high}: set your cell count', decided=False)
