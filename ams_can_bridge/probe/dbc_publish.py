# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What a dbc device would publish from the frames probe heard (every ``--dbc`` pair, every profile).

The frames of the mapped messages go through a ``DbcDevice`` with the candidate's own
configuration, as the bridge would read them: probe says the values it would publish, the
frames it would refuse (outside a DBC range, implausible: protocols.dbc_mapping.plan FIELD_BOUNDS),
the mapping's warnings (a unit taken as it is), and writes ``<name>.timeouts`` for the
messages heard slower than the DBC's periods allow (doc/own_bms.md "Timeouts"). A value no
BMS publishes caps the confidence: such a candidate is not written.
"""
from __future__ import annotations

import math
from typing import Any

from ams_can_bridge.devices.base import BatteryReport
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.protocols.dbc_mapping.plan import ARRAY_LABELS, LEARNED_PERIODS, Plan
from ams_can_bridge.probe.evidence import Candidate
from ams_can_bridge.probe.traffic import Traffic

# What a BMS's published values can be (the IVT-S's bounds for the pack; a Li-ion, LFP or
# LTO cell): outside them the DBC reads frames that are not this BMS's
PLAUSIBLE = {'voltage': (0.0, 1500.0), 'current': (-4000.0, 4000.0),
             'percentage': (0.0, 1.0), 'temperature': (-60.0, 150.0)}
PLAUSIBLE_ARRAYS = {'cell_voltage': (0.5, 5.0), 'cell_temperature': (-60.0, 150.0)}
UNITS = {'voltage': 'V', 'current': 'A', 'temperature': 'degC'}
IMPLAUSIBLE = 0.45  # the confidence of a match whose values cannot be a BMS's: not written


def read_back(config: dict[str, Any], plan: Plan, traffic: Traffic) -> DbcDevice:
    """Feed the frames heard to a dbc device with this configuration (a profile, files)."""
    now = traffic.last if traffic.last == traffic.last else 0.0
    device = DbcDevice('probe', config, lambda: now)
    frames: list[tuple[float, int, bytes]] = []
    later: list[tuple[int, bytes]] = []
    for message in plan.messages:
        entry = traffic.get(message.frame_id, message.is_extended_id)
        if entry is not None:
            frames += [(stamp, entry.can_id, data) for stamp, data in entry.samples]
            sampled = set(entry.payloads)  # a multiplexer value first heard after the samples
            later += [(entry.can_id, d) for d in entry.by_byte0.values() if d not in sampled]
    for _, can_id, data in sorted(frames, key=lambda f: f[0]):
        device.handle_frame(can_id, data, now)
    for can_id, data in later:
        device.handle_frame(can_id, data, now)
    return device


def say_published(cand: Candidate, device: DbcDevice, report: BatteryReport,
                  title: str) -> None:
    """
    Say what the bridge would publish, what it would refuse, and the mapping's warnings.

    A value no ``title`` sends (PLAUSIBLE, or refused by the device as implausible) caps
    the confidence at IMPLAUSIBLE: the candidate is not written.
    """
    cand.evidence.append('the bridge would publish ' + published(report))
    if device.frames_malformed:
        cand.evidence.append(f'{device.frames_malformed} of the frames read count as '
                             f'malformed (the last: {device.last_malformed})')
    for warning in device.warnings:
        cand.notes.append(f'mapping warning: {warning}')
    odd = ', '.join(filter(None, [implausible(report)] + [
        text for text, _ in device.implausible.values()]))
    if odd:
        cand.confidence = min(cand.confidence, IMPLAUSIBLE)
        cand.notes.append(f'not written: {odd}: no {title} sends that; its DBC is '
                          'reading frames of another sender, or with the wrong unit')


def published(report: BatteryReport) -> str:
    """Write the values of a BatteryState as probe reports them."""
    parts = [f'{getattr(report, key):.4g} {unit}' if math.isfinite(getattr(report, key))
             else f'{key} unknown' for key, unit in UNITS.items()]
    parts.insert(2, f'SoC {100 * report.percentage:.4g} %' if math.isfinite(report.percentage)
                 else 'SoC unknown')
    for key in PLAUSIBLE_ARRAYS:
        values = [v for v in getattr(report, key) if math.isfinite(v)]
        count = len(getattr(report, key))
        if count:
            ends = (f'{min(values):.4g}', f'{max(values):.4g}') if values else ()
            span = list(dict.fromkeys(ends))  # one value when all read alike
            parts.append(f'{len(values)} of {count} {ARRAY_LABELS[key]} read'
                         + (f' ({"..".join(span)})' if span else ''))
    return ', '.join(parts)


def implausible(report: BatteryReport) -> str:
    """Say which published value no BMS sends ('' when all are plausible)."""
    odd = [f'{key} {value:.4g}' for key, (low, high) in PLAUSIBLE.items()
           if math.isfinite(value := getattr(report, key)) and not low <= value <= high]
    for key, (low, high) in PLAUSIBLE_ARRAYS.items():
        outside = [v for v in getattr(report, key) if math.isfinite(v) and not low <= v <= high]
        if outside:
            odd.append(f'{len(outside)} {ARRAY_LABELS[key]} outside {low:g}..{high:g}')
    return ', '.join(odd)


def timeouts_setting(cand: Candidate, device: DbcDevice, traffic: Traffic) -> None:
    """
    Write ``timeouts`` for the messages heard slower than their timeout allows.

    A message's timeout (the mapping's, else a few DBC periods) shorter than LEARNED_PERIODS
    x the period heard (x the multiplexer values or positions of a rotation) would expire
    between its frames until the device has learned the rate: the params file gives it
    from the start. The primary's silence is stale_timeout's (written beside).
    """
    plan, items, why = device.plan, [], []
    for m, message in enumerate(plan.messages):
        entry = traffic.get(message.frame_id, message.is_extended_id)
        if m == plan.primary or entry is None or not entry.period_s == entry.period_s:
            continue
        rotation = max(1, len(device.arrivals[m]))
        need = LEARNED_PERIODS * entry.period_s * rotation
        current = plan.timeouts.get(m, device.stale_timeout)
        if need > current:
            seconds = math.ceil(10 * need) / 10
            items.append(f'{message.name}={seconds:g}')
            why.append(f'{message.name} heard every {entry.period_s:.3g} s'
                       + (f' ({rotation} groups a rotation)' if rotation > 1 else '')
                       + f', its timeout would be {current:.3g} s '
                       f'({plan.timeout_origin.get(m, "stale_timeout")})')
    if items:
        cand.set('timeouts', items, '; '.join(why) + f': {LEARNED_PERIODS} x the period '
                 'heard, so its values do not expire between frames')
