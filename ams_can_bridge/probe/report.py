# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What probe found, in words (the default) or as JSON (``--json``, for scripts).

Each device with its IDs, evidence, confidence and settings (decided, or what to check),
the conflicts, and every ID no device explains with its count, DLCs and rate.
"""
from __future__ import annotations

import json
import math
from typing import Any

from ams_can_bridge.probe.evidence import Candidate, Setting
from ams_can_bridge.probe.recognise import Findings
from ams_can_bridge.probe.traffic import id_label, IdTraffic, MAX_IDS, rate_text, Traffic

UNPLACED_LINES = 60  # IDs listed in the text report (the busiest); --json lists them all


def _setting_text(s: Setting) -> str:
    head = f'{s.key} = {s.value!r}' if s.decided else f'({s.key}: not decided)'
    return f'{head}: {s.why}'


def _device_text(cand: Candidate) -> list[str]:
    state = ('written' if cand.written else
             'not written (low confidence)' if cand.writable else 'not written')
    lines = [f'  {cand.name}: {cand.title}, confidence {cand.level} ({cand.confidence:.2f}), '
             f'{state}', f'    IDs: {cand.ids_text()}']
    lines += [f'    - {text}' for text in cand.evidence]
    lines += [f'    setting {_setting_text(s)}' for s in cand.settings]
    lines += [f'    note: {text}' for text in cand.notes]
    return lines


def _dlcs(entry: IdTraffic) -> str:
    return '/'.join(str(n) for n in sorted(entry.dlcs))


def text(findings: Findings, traffic: Traffic, source: str) -> str:
    """Return the report in words."""
    lines = [f'probe: {traffic.frames:,} frames from {source} over {traffic.span_s:.1f} s, '
             f'{len(traffic.ids)} IDs'
             + (f', {traffic.error_frames} error frames' if traffic.error_frames else '')]
    if traffic.unkept_frames:
        lines.append(f'{traffic.unkept_frames:,} frames of IDs beyond the first {MAX_IDS} '
                     'not kept: a battery bus has far fewer IDs (noise, a fuzzer, another bus?)')
    lines.append(f'devices found: {len(findings.devices)}'
                 + ('' if findings.devices else ' (no frame pattern of a known device)'))
    for cand in findings.devices:
        lines += _device_text(cand)
    if findings.failures:
        lines.append('recognisers a frame stopped (their devices are not reported; '
                     'please report it with the frame):')
        lines += [f'  - {text}' for text in findings.failures]
    if findings.conflicts:
        lines.append('conflicts (two candidates for the same IDs):')
        lines += [f'  - {c.text()}' for c in findings.conflicts]
    if findings.unplaced:
        lines.append(f'IDs no device explains: {len(findings.unplaced)}')
        lines.append(f'  {"ID":<11} {"count":>8} {"DLC":>5} {"rate":>10}')
        busiest = sorted(findings.unplaced, key=lambda e: -e.count)[:UNPLACED_LINES]
        lines += [f'  {e.label():<11} {e.count:>8} {_dlcs(e):>5} {rate_text(e.rate_hz):>10}'
                  for e in sorted(busiest, key=lambda e: (e.extended, e.can_id))]
        if len(findings.unplaced) > UNPLACED_LINES:
            lines.append(f'  ... and {len(findings.unplaced) - UNPLACED_LINES} more (fewer '
                         'frames each; all in --json)')
    else:
        lines.append('every ID heard is explained by a device above')
    return '\n'.join(lines)


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def as_data(findings: Findings, traffic: Traffic, source: str,
            live: dict[str, Any] | None = None) -> dict[str, Any]:
    """Return the report as plain data."""
    def ids(cand: Candidate) -> list[dict[str, Any]]:
        return [{'id': i, 'extended': e, 'label': id_label(i, e)}
                for i, e in sorted(cand.ids, key=lambda k: (k[1], k[0]))]
    return {
        'source': source, 'live': live, 'frames': traffic.frames,
        'error_frames': traffic.error_frames, 'span_s': traffic.span_s,
        'unkept_frames': traffic.unkept_frames,
        'devices': [{
            'name': c.name, 'type': c.type, 'title': c.title, 'confidence': c.confidence,
            'level': c.level, 'written': c.written, 'ids': ids(c), 'evidence': c.evidence,
            'settings': [{'key': s.key, 'value': s.value, 'decided': s.decided, 'why': s.why}
                         for s in c.settings],
            'notes': c.notes} for c in findings.devices],
        'conflicts': [{'kept': c.kept.title, 'dropped': c.dropped.title,
                       'both_kept': bool(c.decision),  # both stay, the IDs with kept
                       'ids': sorted(i for i, _ in c.ids), 'text': c.text()}
                      for c in findings.conflicts],
        'failures': findings.failures,
        'unplaced': [{'id': e.can_id, 'extended': e.extended, 'label': e.label(),
                      'count': e.count, 'dlcs': sorted(e.dlcs),
                      'rate_hz': _finite(e.rate_hz)} for e in findings.unplaced],
    }


def as_json(findings: Findings, traffic: Traffic, source: str,
            live: dict[str, Any] | None = None) -> str:
    """Return the report as JSON."""
    return json.dumps(as_data(findings, traffic, source, live), indent=2, default=str)
