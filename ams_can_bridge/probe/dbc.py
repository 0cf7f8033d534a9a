# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Any BMS from its DBC and mapping (``--dbc FILE --mapping FILE``; doc/protocols.md section 8).

The mapping names the messages the dbc device reads
(``protocols.dbc_mapping.mapping.load_plan``, the device's own check of both files). Each of
them is looked for by ID: heard, with a length the DBC message fits in, and with values
inside the signals' DBC ranges (the compiled decoder the device uses says which are not). The
primary message must be among them: it makes the BatteryState. The frames heard then go
through the dbc device as the bridge would read them (``probe.dbc_publish``): what it would
publish and refuse, the mapping's warnings, the timeouts the rates heard need.
``match_plan`` is what a shipped profile (foxBMS 2, Orion BMS 2) reuses to recognise itself.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import os
import re

from ams_can_bridge.protocols.dbc_mapping.mapping import load_plan
from ams_can_bridge.protocols.dbc_mapping.plan import MappingError, Plan, resolve_path
from ams_can_bridge.errors import ConfigError, MalformedFrameError
from ams_can_bridge.probe.dbc_publish import read_back, say_published, timeouts_setting
from ams_can_bridge.probe.evidence import Candidate, stale_setting
from ams_can_bridge.probe.traffic import id_label, Key, rate_text, Traffic

DEFAULT_STALE_S = 1.0  # the dbc device's 5 x 0.2 s


@dataclass
class PlanMatch:
    """How well the traffic fits the messages of a mapping."""

    score: float
    primary_heard: bool
    ids: set[Key] = field(default_factory=set)
    evidence: list[str] = field(default_factory=list)
    primary_period_s: float = float('nan')


def match_plan(traffic: Traffic, plan: Plan) -> PlanMatch:
    """Look for every message of a mapping in the traffic: heard, long enough, in range."""
    match = PlanMatch(0.0, False)
    fits = 0
    for index, message in enumerate(plan.messages):
        entry = traffic.get(message.frame_id, message.is_extended_id)
        where = f'{message.name} {id_label(message.frame_id, message.is_extended_id)}'
        if entry is None:
            match.evidence.append(f'{where}: not heard')
            continue
        if min(entry.dlcs) < message.length:
            match.evidence.append(f'{where}: DLC {min(entry.dlcs)}, the DBC needs '
                                  f'{message.length}')
            continue
        bad: set[str] = set()
        try:
            for data in entry.payloads:
                _, out_of_range = message.decode(data)
                bad |= {message.signals[i].name + (
                    f' (or beyond {plan.bounds[(index, i)]})' if (index, i) in plan.bounds
                    else '') for i in out_of_range}
        except MalformedFrameError as exc:
            match.evidence.append(f'{where}: {exc.reason}')
            continue
        match.ids.add(entry.key)
        if bad:
            match.evidence.append(f'{where}: {entry.count} frames, outside the DBC range: '
                                  + ', '.join(sorted(bad)))
            continue
        fits += 1
        match.evidence.append(f'{where}: {entry.count} frame(s), {rate_text(entry.rate_hz)}, '
                              'every value inside its DBC range')
        if index == plan.primary:
            match.primary_heard = True
            match.primary_period_s = entry.period_s
    match.score = fits / len(plan.messages) if plan.messages else 0.0
    return match


def instance_name(path: str) -> str:
    """Return an instance name from a file name: letters, digits and underscores."""
    stem = os.path.splitext(os.path.basename(path))[0]
    name = re.sub(r'[^0-9A-Za-z_]+', '_', stem).strip('_').lower()
    return name if name and not name[0].isdigit() else f'bms_{name}'


class DbcRecogniser:
    """The recogniser of the DBC and mapping pairs given on the command line."""

    def __init__(self, pairs: list[tuple[str, str]]) -> None:
        """Load and check every pair now; ConfigError names what is wrong with one."""
        self.plans: list[tuple[str, str, Plan]] = []
        for dbc_file, mapping_file in pairs:
            try:
                plan = load_plan(dbc_file, mapping_file)
            except MappingError as exc:
                raise ConfigError(f'--dbc {dbc_file} --mapping {mapping_file}: '
                                  + '; '.join(str(exc).splitlines())) from None
            self.plans.append((str(resolve_path(dbc_file).resolve()),
                               str(resolve_path(mapping_file).resolve()), plan))

    def __call__(self, traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
        """Return one candidate per pair whose messages were heard."""
        out = []
        for dbc_file, mapping_file, plan in self.plans:
            match = match_plan(traffic, plan)
            if not match.ids:
                continue
            name = instance_name(mapping_file)
            cand = Candidate('dbc', name, f'{os.path.basename(dbc_file)} ({name})',
                             match.score if match.primary_heard else min(match.score, 0.4),
                             frozenset(match.ids), match.evidence, user_given=True)
            device = read_back({'dbc_file': dbc_file, 'mapping_file': mapping_file}, plan,
                               traffic)
            if match.primary_heard:
                say_published(cand, device, device.battery_report(), 'BMS')
            else:
                cand.notes.append('the primary message was not heard in range: the device '
                                  'would publish nothing')
                cand.notes += [f'mapping warning: {w}' for w in device.warnings]
            cand.set('dbc_file', dbc_file, 'the DBC given')
            cand.set('mapping_file', mapping_file, 'the mapping given')
            stale_setting(cand, match.primary_period_s, DEFAULT_STALE_S,
                          'the primary message comes')
            timeouts_setting(cand, device, traffic)
            out.append(cand)
        return out
