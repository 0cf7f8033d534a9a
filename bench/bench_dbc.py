# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A dbc device against the built-in AMS device, per frame, for the same traffic, in one run.

The AMS simulator's frames (``--banks`` banks, ``--seconds`` of simulated time: status at
10 Hz, cells and temperatures every second) go to two devices on the same frames: the
built-in ``ams`` device and a ``dbc`` device on msg_defs/ams.dbc with
config/ams_dbc_mapping.yaml (our AMS as a team's own BMS). Per frame each does what the
bridge's receive thread does: ``handle_frame`` and, on a primary frame, ``battery_report``
(the BatteryState it publishes). CPU per frame (``time.thread_time``), best and median of
``--passes`` passes, and the ratio dbc / ams (target: at most 1.5x). Also reports the
compiled decoder alone against cantools ``decode_message`` on the same frames.

Run: ``.venv/bin/python bench/bench_dbc.py [--json]``. Compare ratios, not absolute figures.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.protocols.common import load_dbc
from ams_can_bridge.sim.ams import AmsSimulator

REPO = Path(__file__).resolve().parents[1]
TARGET = 1.5


def frames(banks: int, seconds: float) -> list[tuple[int, bytes]]:
    """Return what the AMS simulator sends in ``seconds`` of simulated time."""
    sim = AmsSimulator(name='ams', bank_count=banks)
    out, t = [], 0.0
    while t < seconds:
        out += [(f.arbitration_id, bytes(f.data)) for f in sim.tick(t)]
        t += 0.01
    return out


def per_frame_us(device, traffic: list[tuple[int, bytes]]) -> float:
    """Run the traffic through one device as the receive thread does; us of CPU a frame."""
    handle, report = device.handle_frame, device.battery_report
    start = time.thread_time()
    for can_id, data in traffic:
        if handle(can_id, data, 0.0):
            report()
    return (time.thread_time() - start) / len(traffic) * 1e6


def run(banks: int, seconds: float, passes: int) -> dict:
    """Measure both devices alternately, pass after pass; return the figures."""
    traffic = frames(banks, seconds)
    clock = [0.0]
    ams = AmsDevice('ams', {'bank_count': banks, 'stale_timeout': 0.5}, lambda: clock[0])
    dbc = DbcDevice('pack', {'dbc_file': str(REPO / 'msg_defs' / 'ams.dbc'),
                             'mapping_file': str(REPO / 'config' / 'ams_dbc_mapping.yaml'),
                             'stale_timeout': 0.5}, lambda: clock[0])
    results: dict[str, list[float]] = {'ams': [], 'dbc': [], 'compiled': [], 'cantools': []}
    db = load_dbc('ams')
    by_id = {m.frame_id: m for m in dbc.plan.messages}
    decodable = [(i, d) for i, d in traffic if i in by_id]
    for _ in range(passes):
        results['ams'].append(per_frame_us(ams, traffic))
        results['dbc'].append(per_frame_us(dbc, traffic))
        start = time.thread_time()
        for can_id, data in decodable:
            by_id[can_id].decode(data)
        results['compiled'].append((time.thread_time() - start) / len(decodable) * 1e6)
        start = time.thread_time()
        for can_id, data in decodable:
            db.decode_message(can_id, data, decode_choices=False)
        results['cantools'].append((time.thread_time() - start) / len(decodable) * 1e6)
    best = {k: min(v) for k, v in results.items()}
    median = {k: statistics.median(v) for k, v in results.items()}
    return {'frames': len(traffic), 'banks': banks, 'best_us': best, 'median_us': median,
            'ratio_best': best['dbc'] / best['ams'],
            'ratio_median': median['dbc'] / median['ams'],
            'target': TARGET, 'met': median['dbc'] / median['ams'] <= TARGET}


def main() -> None:
    """Print the table (or JSON) of one run."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--banks', type=int, default=5)
    parser.add_argument('--seconds', type=float, default=60.0)
    parser.add_argument('--passes', type=int, default=7)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    figures = run(args.banks, args.seconds, args.passes)
    if args.json:
        print(json.dumps(figures))
        return
    print(f'{figures["frames"]} AMS frames ({args.banks} banks), us of CPU per frame '
          '(handle_frame + battery_report on each primary):')
    for key, label in (('ams', 'built-in ams device'), ('dbc', 'dbc device, AMS mapping'),
                       ('compiled', 'dbc decode alone (compiled)'),
                       ('cantools', 'cantools decode_message')):
        print(f'  {label:<30} best {figures["best_us"][key]:7.2f}   '
              f'median {figures["median_us"][key]:7.2f}')
    verdict = 'met' if figures['met'] else 'NOT met'
    print(f'  dbc / ams: {figures["ratio_median"]:.2f}x median, {figures["ratio_best"]:.2f}x '
          f'best (target <= {TARGET}x: {verdict})')


if __name__ == '__main__':
    main()
