# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Run the recognisers, settle candidates for the same IDs, link devices, list what is left.

A recogniser is a function ``(traffic, found so far) -> new candidates``; it may also refine
a candidate found before it (add or decide a setting), which is how a decision that needs
more than one device's frames plugs in. Each device type's descriptor names its recognisers
(``registry.py``); they run in ``INSTALLED`` order (the types' order), then the DBC pairs
given on the command line. Two candidates that explain one ID cannot both be right: the one
that explains everything the other does and more wins, else the more confident one (the
user's own DBC on a tie), and the other is reported as a conflict.

``sma_voltage.recognise`` is such a refiner: it decides the sma candidate's
``voltage_scale`` from the battery's own 0x351 limits and cells. The shipped ``dbc`` profiles
come last (``profiles.py``): they leave a device of the bridge its IDs (a candidate's
``deferred``, reported as a conflict that keeps both) and take over an SMA battery that is
their own pack.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Callable, Sequence

from ams_can_bridge.errors import ProtocolError
from ams_can_bridge.probe import pack
from ams_can_bridge.probe.evidence import Candidate, Conflict, MEDIUM, WEAK
from ams_can_bridge.probe.traffic import IdTraffic, Traffic
from ams_can_bridge.registry import DESCRIPTORS, DEVICE_TYPES, load

Recogniser = Callable[[Traffic, list[Candidate]], list[Candidate]]


def _installed() -> tuple[tuple[Recogniser, ...], tuple[str, ...]]:
    """Load every device type's recognisers: (them, why one did not load)."""
    loaded: list[Recogniser] = []
    failed = []
    for found in DESCRIPTORS.values():
        for path in found.recognisers:
            try:
                loaded.append(load(path))
            except Exception as exc:  # a plugin's bug: the others still run, probe says why
                failed.append(f'{found.name}: recogniser {path} failed to load: '
                              f'{type(exc).__name__}: {exc}')
    return tuple(loaded), tuple(failed)


INSTALLED, LOAD_FAILURES = _installed()
PACK_VOLTAGE_AGREEMENT = 0.05  # an IVT-S voltage within 5 % of the AMS cell sum measures the pack
MIN_FRAMES = 3  # a device repeats its frames: an ID heard once or twice is no device
# Repetition is judged only on a recording this long: every device here repeats its frames
# at least once a second, while a short excerpt (a capture of a few frames, as vendors and
# forums publish them) may show each frame once and is still evidence of its payloads.
JUDGE_MIN_SPAN_S = 5.0
# A backlog: every frame of a candidate came within this share of the listening (an
# adapter's or a pty's buffer read at once), not a device sending.
BACKLOG_SHARE = 0.05


@dataclass
class Findings:
    """What probe found: the devices kept (in params-file order), conflicts, the rest."""

    devices: list[Candidate] = field(default_factory=list)
    conflicts: list[Conflict] = field(default_factory=list)
    unplaced: list[IdTraffic] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)  # recognisers stopped or not loaded
    # what the bridge's devices read from the frames heard (the pack section's guesses)
    readings: dict[str, pack.Reading] = field(default_factory=dict)

    @property
    def written(self) -> list[Candidate]:
        """Return the devices the params file lists."""
        return [c for c in self.devices if c.written]


def recognise(traffic: Traffic, recognisers: Sequence[Recogniser] = INSTALLED) -> Findings:
    """Run every recogniser on the traffic and settle what they found."""
    found: list[Candidate] = []
    failures = list(LOAD_FAILURES)
    for recogniser in recognisers:
        try:
            found += recogniser(traffic, found)
        except ProtocolError as exc:  # a frame it did not expect: the others still run
            failures.append(f'{recogniser.__module__.rpartition(".")[2]}: {exc}')
    for cand in found:
        judge_traffic(traffic, cand)
    kept, conflicts = settle([c for c in found if c.confidence >= WEAK])
    conflicts += [Conflict(other, cand, ids, why) for cand in kept
                  for other, ids, why in cand.deferred if any(k is other for k in kept)]
    kept.sort(key=lambda c: (DEVICE_TYPES.index(c.type), not c.written, -c.confidence))
    _name(kept)
    _link(kept)
    claimed = set().union(*(c.ids for c in kept))
    written = [c for c in kept if c.written]
    read = pack.readings(traffic, written) if len(pack.batteries(written)) > 1 else {}
    return Findings(kept, conflicts, [e for e in traffic if e.key not in claimed], failures,
                    read)


def judge_traffic(traffic: Traffic, cand: Candidate) -> None:
    """
    Lower the confidence of a candidate whose frames do not come as a device sends them.

    Whatever its payloads say: a device repeats its frames (an ID heard fewer than
    MIN_FRAMES times is no evidence), on a cycle (frames at random times: noise, not
    reported), and over the time probe listened (every frame within a short burst of the
    listening is a backlog read at once: reported, never written). Judged only where the
    recording is JUDGE_MIN_SPAN_S long.
    """
    entries = [e for key in cand.ids if (e := traffic.ids.get(key)) is not None]
    if not entries or traffic.span_s < JUDGE_MIN_SPAN_S:
        return
    if max(e.count for e in entries) < MIN_FRAMES:
        cand.confidence = 0.0
        return
    if not any(e.periodic for e in entries):
        cand.confidence = min(cand.confidence, WEAK / 2)  # not even reported
        return
    first = min(e.first for e in entries)
    last = max(e.last for e in entries)
    span = traffic.span_s
    if last - first <= BACKLOG_SHARE * span:
        frames = sum(e.count for e in entries)
        rate = frames / (last - first) if last > first else math.inf
        cand.confidence = min(cand.confidence, MEDIUM - 0.05)
        cand.notes.append(
            f'all its {frames} frames came within {last - first:.3g} s of {span:.3g} s ('
            + (f'{rate / 1000:.3g} kHz' if math.isfinite(rate) else 'at once')
            + '), then none: a backlog read at once (an adapter or pty buffer, a device '
            'heard before), not a device sending now; listen again')


def settle(candidates: list[Candidate]) -> tuple[list[Candidate], list[Conflict]]:
    """
    Keep the candidates that claim no ID of a better one; the others are conflicts.

    Better: the one that explains every ID of its rivals and more (if it is at least of
    medium confidence), else the more confident, then the one explaining more IDs, then the
    user's own DBC. A weak match set aside is not reported.
    """
    kept: list[Candidate] = []
    conflicts = []

    def drop(winner: Candidate, loser: Candidate) -> None:
        if loser.confidence >= MEDIUM:
            conflicts.append(Conflict(winner, loser, winner.ids & loser.ids))
    for cand in sorted(candidates, key=lambda c: (c.confidence, len(c.ids), c.user_given),
                       reverse=True):
        rivals = [k for k in kept if k.ids & cand.ids]
        if not rivals:
            kept.append(cand)
        elif cand.confidence >= MEDIUM and all(cand.ids > r.ids for r in rivals):
            kept = [k for k in kept if k not in rivals] + [cand]
            for rival in rivals:
                drop(cand, rival)
        else:
            drop(rivals[0], cand)
    return kept, conflicts


def _name(devices: list[Candidate]) -> None:
    """Make the instance names unique: the first of a name keeps it, then name_2, ..."""
    used: set[str] = set()
    for cand in devices:
        name, n = cand.name, 1
        while name in used:
            n += 1
            name = f'{cand.name}_{n}'
        cand.name = name
        used.add(name)


def _link(devices: list[Candidate]) -> None:
    """Decide what needs two devices: which IVT-S result measures the AMS pack."""
    amss = [c for c in devices if c.type == 'ams' and c.written]
    shunts = [c for c in devices if c.type == 'ivt_s' and c.written]
    for cand in amss:
        if not shunts:
            cand.notes.append('no IVT-S heard: the AMS voltage is the sum of its cells and '
                              'the current is unknown (NaN)')
            continue
        shunt = shunts[0]
        cand.set('current_sensor', shunt.name, f'the IVT-S at {shunt.title[len("IVT-S at "):]}')
        cells: float | None = cand.facts.get('cell_sum_v')
        voltages: dict[str, float] = shunt.facts.get('voltages', {})
        near = sorted((abs(v - cells), name) for name, v in voltages.items()) \
            if cells is not None else []
        if cells is not None and near and near[0][0] <= PACK_VOLTAGE_AGREEMENT * cells:
            name = near[0][1]
            others = ', '.join(f'{n} {voltages[n]:.1f} V' for _, n in near[1:])
            cand.set('pack_voltage_channel', name,
                     f'{name} reads {voltages[name]:.1f} V, the AMS cells add up to '
                     f'{cells:.1f} V' + (f' ({others})' if others else ''))
        else:
            heard = ', '.join(f'{n} {v:.1f} V' for n, v in voltages.items())
            cand.set('pack_voltage_channel', 'U1', 'check: ' + (
                f'no IVT-S voltage near the AMS cell sum {cells:.1f} V ({heard})'
                if cells is not None and voltages else 'no IVT-S voltage or AMS cell sum to '
                'compare') + ': the input wired across the pack', decided=False)
