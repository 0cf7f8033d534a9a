# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The IVT-S shunt at any base ID (doc/protocols.md section 2), from its result frames.

A result frame is DLC 6 with its MuxID (0 I .. 7 Wh) in byte 0 and a 4-bit counter in
byte 1: an ID whose frames all carry one MuxID k is result k of the sensor at ID - k.
Which results run, and at which cycle, is what was heard. The byte order is the one in
which I, U1..U3, T and W stay inside what an IVT-S can measure (the other order reads a
varying value as thousands of amperes or volts). The current's sign convention cannot be
read from any frame (it depends on how the shunt is mounted): it is written as a check.
"""
from __future__ import annotations

from typing import Any

from ams_can_bridge.errors import ConfigError, MalformedFrameError
from ams_can_bridge.probe.evidence import Candidate, stale_setting
from ams_can_bridge.probe.traffic import IdTraffic, Key, Traffic
from ams_can_bridge.protocols import ivt_s_commands as cmd
from ams_can_bridge.protocols.ivt_s import (
    BYTE_ORDERS, COMMAND_ID, DBC_NAME, DLC, IvtMux, IvtSCodec, RESPONSE_ID, SI_UNIT)

DEFAULT_STALE_S = 0.5  # the device's 5 x 0.1 s
# Bounds of a plausible reading (raw units: mA, mV, 0.1 degC, W). The IVT-S measures up to
# +-2500 A continuously (Isabellenhuette, IVT-S datasheet V1.01, 2018); 1500 V is above any
# traction pack (800 V class). A small value read in the wrong byte order is millions of
# amperes or volts. The counters As and Wh can hold anything and decide nothing.
PLAUSIBLE_RAW = {IvtMux.I: 4_000_000, IvtMux.U1: 1_500_000, IvtMux.U2: 1_500_000,
                 IvtMux.U3: 1_500_000, IvtMux.T: 2_000, IvtMux.W: 6_000_000}


def _results(traffic: Traffic) -> dict[int, dict[IvtMux, IdTraffic]]:
    """Return the result frames heard, by the base ID they imply."""
    bases: dict[int, dict[IvtMux, IdTraffic]] = {}
    for entry in traffic.of_width(False):
        muxes = set(entry.by_byte0)
        if set(entry.dlcs) != {DLC} or len(muxes) != 1:
            continue
        mux = muxes.pop()
        if 0 <= mux <= 7 and entry.can_id - mux >= 0:
            bases.setdefault(entry.can_id - mux, {})[IvtMux(mux)] = entry
    return bases


def _counter(entry: IdTraffic) -> tuple[bool, str]:
    """Tell whether the 4-bit counter runs (a constant step, every value), and say how."""
    counters = [data[1] & 0x0F for data in entry.payloads]
    steps = {(b - a) & 0x0F for a, b in zip(counters, counters[1:])}
    if len(counters) < 3:
        return False, f'{len(counters)} frame(s): too few to see the counter'
    if steps == {0}:
        return False, 'counter stuck'
    if len(steps) == 1:
        step = steps.pop()
        late = ' a frame (frames not logged, or a faster internal cycle)'
        return True, f'counter +{step}' + ('' if step == 1 else late)
    return len(set(counters)) > 3, f'counter steps {sorted(steps)}'


def _values(codecs: dict[str, IvtSCodec], entry: IdTraffic) -> dict[str, list[int]]:
    out = {}
    for order, codec in codecs.items():
        try:
            out[order] = [codec.decode(entry.can_id, data).raw for data in entry.payloads]
        except MalformedFrameError:
            out[order] = []
    return out


def _shown(codec: IvtSCodec, can_id: int, data: bytes, unit: str, digits: int = 6) -> str:
    """Return a result as one byte order reads it, or why that order cannot read it."""
    try:
        return f'{codec.decode(can_id, data).value:.{digits}g} {unit}'
    except MalformedFrameError:  # out of the protocol's range (a temperature past 200 degC)
        return 'nothing plausible (out of range)'


def _byte_order(codecs: dict[str, IvtSCodec],
                results: dict[IvtMux, IdTraffic]) -> tuple[str | None, list[str]]:
    """Decide big or little from the results that can tell; the evidence of each."""
    votes: dict[str, list[str]] = {order: [] for order in BYTE_ORDERS}
    for kind, entry in sorted(results.items()):
        limit = PLAUSIBLE_RAW.get(kind)
        if limit is None:
            continue
        raws = _values(codecs, entry)
        fits = [o for o in BYTE_ORDERS if raws[o] and all(abs(r) <= limit for r in raws[o])]
        if len(fits) == 1:
            order = fits[0]
            other = 'little' if order == 'big' else 'big'
            last = entry.payloads[-1]
            unit = SI_UNIT[kind]
            votes[order].append(
                f'{DBC_NAME[kind]} reads {_shown(codecs[order], entry.can_id, last, unit)} '
                f'{order}-endian, {_shown(codecs[other], entry.can_id, last, unit, 3)} '
                f'{other}-endian ([{last.hex(" ").upper()}])')
    decided = [o for o in BYTE_ORDERS if votes[o]]
    if len(decided) == 1:
        return decided[0], votes[decided[0]]
    if decided:
        return None, ['results disagree: ' + '; '.join(votes['big'] + votes['little'])
                      + ' (the bridge reads one byte order for all results)']
    return None, []


def recognise(traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
    """Return one candidate per base ID with result frames; the one with I first."""
    out = [cand for base, results in _results(traffic).items()
           if (cand := _candidate(traffic, base, results)) is not None]
    out.sort(key=lambda c: (not c.facts['has_current'], -c.confidence))
    for extra in out[1:]:
        extra.writable = False
        extra.notes.append(
            f'not written: the params file has {out[0].title} already, and a second ivt_s '
            'instance needs command and answer IDs of its own (command_id, answer_id, set in '
            'the sensor); if these results belong to the same sensor, its result IDs were '
            'moved one by one and the bridge reads only base_id + 0..7')
    return out


def _candidate(traffic: Traffic, base: int,
               results: dict[IvtMux, IdTraffic]) -> Candidate | None:
    try:
        codecs = {order: IvtSCodec(base, order) for order in BYTE_ORDERS}
    except ConfigError:
        return None
    counting = {kind: _counter(entry) for kind, entry in results.items()}
    jumps = [k for k, (_, how) in counting.items() if how.startswith('counter +')
             and not how.startswith('counter +1')]
    running = sum(ok for ok, _ in counting.values())
    if not running:
        return None  # a DLC-6 frame with a constant first byte, nothing more
    order, order_evidence = _byte_order(codecs, results)
    score = 0.3 + (0.3 if running else 0) + (0.2 if len(results) > 1 else 0) + (
        0.2 if order else 0)
    cycles = ', '.join(f'{DBC_NAME[k]} 0x{e.can_id:03X} every {e.period_s * 1000:.3g} ms '
                       f'({counting[k][1]})' for k, e in sorted(results.items()))
    off = [DBC_NAME[k] for k in IvtMux if k not in results]
    cand = Candidate('ivt_s', 'ivt_s', f'IVT-S at base 0x{base:03X}', min(score, 1.0),
                     frozenset(e.key for e in results.values()),
                     [f'results {cycles}' + (f'; not heard: {", ".join(off)}' if off else '')])
    cand.facts['has_current'] = IvtMux.I in results
    if jumps:
        cand.notes.append('the counters of ' + ', '.join(DBC_NAME[k] for k in jumps)
                          + ' step by more than one a frame: the ivt_s diagnostics will warn '
                          'of lost frames')
    ids: set[Key] = set(cand.ids)
    for can_id, lowest in ((COMMAND_ID, cmd.SET_CONFIG_RESULT),
                           (RESPONSE_ID, cmd.RESP_MEAS_ERROR)):
        entry = traffic.get(can_id)
        if entry is not None and set(entry.dlcs) == {cmd.DLC} and min(entry.by_byte0) >= lowest:
            ids.add(entry.key)
            cand.evidence.append(f'0x{can_id:03X}: {entry.count} IVT-S '
                                 + ('commands (someone configures the sensor)'
                                    if can_id == COMMAND_ID else 'answers'))
    cand.ids = frozenset(ids)
    names = ', '.join(DBC_NAME[k] for k in sorted(results))
    cand.set('base_id', base, f'0x{base:03X}: results {names} at base_id + their MuxID')
    if order:
        cand.set('byte_order', order, '; '.join(order_evidence))
    else:
        cand.set('byte_order', 'big', 'check: ' + ('; '.join(order_evidence) or 'no result '
                 'tells (all zero, or none of I, U1..U3, T, W)') + ': big is the factory '
                 'setting', decided=False)
    current = results.get(IvtMux.I)
    if current is None:
        cand.notes.append('the current result (I) is off: this ivt_s publishes no '
                          'battery_state (its voltages still serve an AMS)')
    else:
        stale_setting(cand, current.period_s, DEFAULT_STALE_S, 'I comes')
        _sign(cand, codecs[order or 'big'], current)
    cand.facts['voltages'] = {kind.name: codecs[order or 'big'].decode(
        entry.can_id, entry.payloads[-1]).value for kind, entry in results.items()
        if kind in (IvtMux.U1, IvtMux.U2, IvtMux.U3)}
    return cand


def _sign(cand: Candidate, codec: IvtSCodec, current: IdTraffic) -> None:
    amps = [codec.decode(current.can_id, data).value for data in current.payloads]
    positive = sum(a > 0 for a in amps) / len(amps)
    mean: Any = sum(amps) / len(amps)
    cand.set('discharge_positive', True,
             'check: no frame tells the sign (it depends on how the shunt is mounted); while '
             f'probe listened I was positive in {positive:.0%} of the frames (mean {mean:+.2f} '
             'A): true if the pack was discharging then', decided=False)
