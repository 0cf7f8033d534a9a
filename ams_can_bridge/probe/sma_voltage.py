# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The 0x356 voltage scale of an SMA-family battery, from its own frames: refines the sma candidate.

0x356's voltage is in SMA's 0.01 V or in the 0.1 V a Discover Lynx II or an Orion BMS 2 send
(doc/protocols.md section 5.2.1). The rule is the bridge's own,
``protocols.sma_scale.decide_voltage_scale``, on the battery's last 0x351 limits and cell
voltages (0x373, or the binary 0x370); no SMA frame carries a cell count, so none is given.
Every 0x356 voltage sampled is weighed: the scale is written when those that settle it agree
(as the device in ``auto`` keeps the first scale settled); when none settles it, or two
settle different scales, it stays a check with the reason and the values.
"""
from __future__ import annotations

from typing import Any

from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.probe.evidence import Candidate
from ams_can_bridge.probe.traffic import Traffic
from ams_can_bridge.protocols.sma import BATTERY_ID, LIMITS_ID, SmaBattery, SmaCodec, SmaLimits
from ams_can_bridge.protocols.sma_dialects import (
    PylontechCellExtremes, VICTRON_BMS_NAME1_ID, VICTRON_CELL_EXTREMES_ID, VictronCellExtremes)
from ams_can_bridge.protocols.sma_scale import (
    decide_voltage_scale, raw_voltage, ScaleDecision, scaled_voltage, SMA_VOLTAGE_SCALE,
    TENTH_VOLT_SCALE)

KEY = 'voltage_scale'
WHAT_TO_SET = ('set 0.1 if the 0.01 V reading is a tenth of the pack, else 0.01 (left out, the '
               "bridge decides from 0x351 when it comes, else assumes SMA's 0.01 with a WARN)")


def recognise(traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
    """Decide voltage_scale on each SMA candidate found so far; add no candidate."""
    for cand in found:
        if cand.type == 'sma' and 'readings' in cand.facts:
            _decide(cand, traffic)
    return []


def _cells(readings: dict[int, Any]) -> tuple[tuple[float, float], str] | None:
    """Return the lowest and highest cell voltage and the frame that said so."""
    for can_id, kind in ((VICTRON_CELL_EXTREMES_ID, VictronCellExtremes),
                         (VICTRON_BMS_NAME1_ID, PylontechCellExtremes)):
        cells = readings.get(can_id)
        if isinstance(cells, kind) and cells.min_cell_v is not None \
                and cells.max_cell_v is not None:
            return (cells.min_cell_v, cells.max_cell_v), f'0x{can_id:03X}'
    return None


def _raw_voltages(traffic: Traffic) -> list[int]:
    """Return the distinct 0x356 voltages sampled, as sent, in the order first heard."""
    entry = traffic.get(BATTERY_ID)
    codec = SmaCodec()
    raws: dict[int, None] = {}
    for data in entry.payloads if entry is not None else []:
        try:
            battery = codec.decode(BATTERY_ID, data)
        except MalformedFrameError:
            continue  # counted malformed by the sma recogniser already
        raw = raw_voltage(battery) if isinstance(battery, SmaBattery) else None
        if raw is not None:
            raws[raw] = None
    return list(raws)


def _inputs(raws: list[int], limits: SmaLimits | None,
            cells: tuple[tuple[float, float], str] | None) -> str:
    """Say every value the decision weighed."""
    low, high = min(raws), max(raws)
    span = f'{low}' if low == high else f'{low}..{high}'
    volts = [f'{_volts(low, s, high)} V at {s:g} V/bit'
             for s in (SMA_VOLTAGE_SCALE, TENTH_VOLT_SCALE)]
    parts = [f'0x356 voltage {span} as sent ({", ".join(volts)})']
    if limits is not None:
        parts.append(f'0x351 limits: charge {_limit(limits.charge_voltage_v)}, discharge '
                     f'{_limit(limits.discharge_voltage_v)}')
    else:
        parts.append('no readable 0x351 limits')
    if cells is not None:
        (vmin, vmax), frame = cells
        parts.append(f'cells {vmin:g}..{vmax:g} V ({frame})')
    else:
        parts.append('no readable cell voltages (0x373, binary 0x370)')
    return ', '.join(parts)


def _limit(volts: float | None) -> str:
    return 'not sent' if volts is None else f'{volts:g} V'


def _volts(low: int, scale: float, high: int) -> str:
    a, b = scaled_voltage(low, scale), scaled_voltage(high, scale)
    return f'{a:g}' if a == b else f'{a:g}..{b:g}'


def _decide(cand: Candidate, traffic: Traffic) -> None:
    readings: dict[int, Any] = cand.facts['readings']
    raws = _raw_voltages(traffic)
    if not raws:
        cand.set(KEY, 'auto', 'check: no 0x356 voltage heard (none, or the 0x8000 "not sent" '
                 f'marker): {WHAT_TO_SET}', decided=False)
        return
    limits = readings.get(LIMITS_ID)
    limits = limits if isinstance(limits, SmaLimits) else None
    cells = _cells(readings)
    decisions = {raw: decide_voltage_scale(raw, limits, cells[0] if cells else None)
                 for raw in raws}
    settled: dict[float, ScaleDecision] = {}
    for decision in decisions.values():
        if decision.scale is not None:
            settled.setdefault(decision.scale, decision)  # the first voltage that settles it
    inputs = _inputs(raws, limits, cells)
    cand.evidence.append('voltage scale: ' + inputs)
    open_count = sum(d.scale is None for d in decisions.values())
    if len(settled) == 1:
        scale, decision = next(iter(settled.items()))
        rest = (f' ({open_count} of the {len(raws)} 0x356 voltages sampled fit both scales '
                'or neither; none fits only the other)' if open_count else '')
        cand.set(KEY, scale, decision.reason + rest)
    elif settled:
        cand.set(KEY, 'auto', 'check: the 0x356 voltages sampled disagree: ' + '; '.join(
            d.reason for d in settled.values()) + f': {WHAT_TO_SET}', decided=False)
    else:
        reason = decisions[raws[-1]].reason
        if limits is None and cells is None:  # the reason names no voltage: say them
            reason = f'{inputs}: nothing that settles it'
        cand.set(KEY, 'auto', f'check: {reason}: {WHAT_TO_SET}', decided=False)
