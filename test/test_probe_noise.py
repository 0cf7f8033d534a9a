# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe on noise and on a backlog: no device from frames that do not come as a device sends them.

Random frames (random IDs, lengths, payloads, times) are no evidence, however a single
payload decodes: a candidate needs repeated frames on a cycle. probe's memory is bounded by
the IDs it keeps, not by the frames. Frames that all came in one burst at the start of a
long listening (an adapter's or a pty's buffer, left over from a device heard before) are a
backlog: reported, never written as a device.
"""
from __future__ import annotations

import random

from ams_can_bridge.probe.recognise import recognise
from ams_can_bridge.probe.report import text
from ams_can_bridge.probe.sources import read_log
from ams_can_bridge.probe import traffic as traffic_module
from ams_can_bridge.probe.traffic import MAX_IDS, Traffic
from probe_variants import BY_NAME


def _random_log(path, frames: int, seed: int = 7, seconds: float = 100.0) -> None:
    rng = random.Random(seed)
    lines = []
    for n in range(frames):
        stamp = rng.uniform(0, seconds)
        extended = rng.random() < 0.5
        can_id = rng.randrange(1 << 29) if extended else rng.randrange(1 << 11)
        data = rng.randbytes(rng.randrange(9))
        label = f'{can_id:08X}' if extended else f'{can_id:03X}'
        lines.append((stamp, f'({stamp:.6f}) can0 {label}#{data.hex().upper()}'))
    lines.sort()
    path.write_text('\n'.join(line for _, line in lines) + '\n')


def test_random_frames_are_no_device_and_memory_is_bounded_by_ids(tmp_path):
    log = tmp_path / 'noise.log'
    _random_log(log, 100_000)
    traffic = read_log(str(log))
    assert traffic.frames == 100_000
    assert len(traffic.ids) == MAX_IDS  # not one summary per random 29-bit ID
    assert traffic.unkept_frames > 0
    findings = recognise(traffic)
    assert findings.devices == [], [c.title for c in findings.devices]
    report = text(findings, traffic, str(log))
    assert 'devices found: 0' in report
    assert f'beyond the first {MAX_IDS} not kept' in report
    assert len(report.splitlines()) < 100  # the busiest unplaced IDs, not all 2048


def test_single_frames_at_random_29_bit_ids_are_no_device(monkeypatch):
    # a single random 8-byte frame at a 29-bit ID decodes as a ZEVA status often enough
    # (before: 219 "BMS16 (standard form)" devices from these frames); every ID kept here
    monkeypatch.setattr(traffic_module, 'MAX_IDS', 10**6)
    rng = random.Random(3)
    traffic = Traffic()
    for stamp in sorted(rng.uniform(0, 60) for _ in range(50_000)):
        traffic.add(rng.randrange(1 << 29), True, rng.randbytes(8), stamp)
    findings = recognise(traffic)
    assert findings.devices == [], [c.title for c in findings.devices][:5]


def test_random_frames_on_the_ids_of_devices_are_no_device(tmp_path):
    # noise on the 11-bit IDs only: every ID is hit about 50 times, at random times
    rng = random.Random(11)
    traffic = Traffic()
    for stamp in sorted(rng.uniform(0, 60) for _ in range(100_000)):
        traffic.add(rng.randrange(1 << 11), False, rng.randbytes(rng.choice((4, 7, 8))),
                    stamp)
    assert recognise(traffic).written == []


def _variant_frames(name: str, seconds: float) -> list[tuple[float, int, bool, bytes]]:
    out = []
    sims = BY_NAME[name].build()
    t = 0.0
    while t < seconds:
        for sim in sims:
            for frame in sim.tick(t):
                out.append((t, frame.arbitration_id, frame.is_extended_id, bytes(frame.data)))
        t += 0.01
    return out


def test_a_backlog_read_at_once_is_not_a_device():
    traffic = Traffic()
    # two seconds of an AMS and IVT-S, left in a buffer and read at once (16 kHz) ...
    old = _variant_frames('ams_3_ivt_little_shifted_results_off', 2.0)
    for n, (_, can_id, ext, data) in enumerate(old):
        traffic.add(can_id, ext, data, n / 16_500)
    # ... then ten seconds of the BMS16 now on the bus, in real time
    for stamp, can_id, ext, data in _variant_frames('bms16_inverter', 10.0):
        traffic.add(can_id, ext, data, 1.0 + stamp)
    findings = recognise(traffic)
    assert [c.type for c in findings.written] == ['bms16']
    backlog = [c for c in findings.devices if c.type in ('ams', 'ivt_s')]
    assert backlog and all(not c.written and c.level != 'high' for c in backlog)
    assert all(any('a backlog read at once' in n for n in c.notes) for c in backlog)


def test_a_device_heard_all_along_is_still_found():
    traffic = Traffic()
    for stamp, can_id, ext, data in _variant_frames('ams_3_ivt_little_shifted_results_off',
                                                    10.0):
        traffic.add(can_id, ext, data, stamp)
    assert {c.type for c in recognise(traffic).written} == {'ams', 'ivt_s'}
