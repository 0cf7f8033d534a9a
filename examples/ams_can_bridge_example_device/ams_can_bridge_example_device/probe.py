# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""How probe recognises the example BMS: an 11-bit ID of DLC 8 that decodes as its status."""
from __future__ import annotations

from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.probe.evidence import Candidate, stale_setting
from ams_can_bridge.probe.traffic import Traffic
from ams_can_bridge_example_device import protocol
from ams_can_bridge_example_device.protocol import ExampleCodec


def recognise(traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
    """Return a candidate per ID whose every payload is a plausible example status."""
    out = []
    for entry in traffic.of_width(False):
        if set(entry.dlcs) != {8}:
            continue
        codec = ExampleCodec(entry.can_id)
        try:
            readings = [codec.decode(entry.can_id, data) for data in entry.payloads]
        except MalformedFrameError:
            continue  # one payload that is not the layout: not this device
        last = readings[-1]
        if not 5.0 <= last.voltage_v <= 1000.0:
            continue
        cand = Candidate(
            'example_bms', 'example_bms', f'example BMS at 0x{entry.can_id:03X}', 0.7,
            frozenset({entry.key}),
            [f'status 0x{entry.can_id:03X}: {entry.count} frames, layout version '
             f'{protocol.LAYOUT_VERSION}, SoC {last.soc_pct} %, {last.voltage_v:g} V'])
        cand.set('base_id', entry.can_id, f'{entry.can_id} (0x{entry.can_id:03X}): the status ID')
        stale_setting(cand, entry.period_s, 5 * protocol.STATUS_PERIOD_S, 'the status comes')
        out.append(cand)
    return out
