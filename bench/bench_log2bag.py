# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag benchmark: CAN log frames per second converted into a bag, beside python-can's read.

The log is what the simulators send (AMS with 5 banks + IVT-S, EVMS3 with 8 BMS12 modules,
BMS16 + SMA) over ``--seconds`` of simulated time, in each format; the reference is a bare
``can.LogReader`` loop over the same file in the same run. Targets: >= 20,000 frames/s, and
(issue 39) at least RATIO_TARGET of the read's rate in the same run.
Run: ``./dev bench`` or ``.venv/bin/python bench/bench_log2bag.py [--seconds 120]``.
Prints one table and, with ``--json PATH``, writes the figures as JSON.
"""
import argparse
import json
import os
import shutil
import tempfile
import time


from ams_can_bridge import registry
from ams_can_bridge.can_io.replay import open_log
from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.sim.recording import write_log

TARGET = 20_000.0  # frames/s
RATIO_TARGET = 0.5  # of python-can's read of the same file, in the same run
DEVICES = {'ams': {'bank_count': 5}, 'ivt_s': {}, 'evms3': {'bms12_modules': 8},
           'bms16': {'send_sma': True}}
PARAMETERS = {'devices': ['ams', 'ivt_s', 'evms3', 'bms16', 'sma'], 'ams.bank_count': 5,
              'evms3.bms12_modules': 8, 'evms3.config.pack_capacity_ah': 100.0}


def simulators() -> list:
    """Return the simulated devices of the frame mix."""
    return [registry.load(registry.SIMULATORS[name])(name=name, **options)
            for name, options in DEVICES.items()]


def bare_read(path: str) -> tuple[int, float]:
    """Return (frames, seconds) of a bare python-can read of the log."""
    start = time.perf_counter()
    reader = open_log(path)
    count = sum(1 for _ in reader)
    reader.stop()
    return count, time.perf_counter() - start


def measure(seconds: float, formats) -> list[dict]:
    """Convert a simulated log of each format; return one figure dict per format."""
    work = tempfile.mkdtemp(prefix='bench_log2bag_')
    rows = []
    try:
        for fmt in formats:
            log = os.path.join(work, f'bus.{fmt}')
            frames = write_log(log, simulators(), seconds)
            read_frames, read_s = bare_read(log)
            start = time.perf_counter()
            summary = convert(log, os.path.join(work, f'bag_{fmt}'), PARAMETERS)
            convert_s = time.perf_counter() - start
            assert summary.frames_read == read_frames == frames, (fmt, summary.frames_read)
            rows.append({'format': fmt, 'frames': frames,
                         'messages': sum(summary.messages.values()),
                         'log2bag_fps': frames / convert_s, 'python_can_read_fps':
                         read_frames / read_s, 'target_fps': TARGET,
                         'met': frames / convert_s >= TARGET})
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return rows


def main() -> None:
    """Measure each format and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=120.0,
                        help='simulated seconds of bus traffic in the log')
    parser.add_argument('--formats', default='log,blf,asc,csv')
    parser.add_argument('--json', default='', help='also write the figures here')
    args, _ = parser.parse_known_args()
    rows = measure(args.seconds, args.formats.split(','))
    print(f'log2bag, {args.seconds:g} s of simulated bus per format (target >= {TARGET:,.0f} '
          'frames/s)')
    print(f'{"format":<7}{"frames":>9}{"messages":>10}{"log2bag fps":>14}'
          f'{"python-can read fps":>21}{"ratio":>8}  target')
    for r in rows:
        print(f'{r["format"]:<7}{r["frames"]:>9}{r["messages"]:>10}{r["log2bag_fps"]:>14,.0f}'
              f'{r["python_can_read_fps"]:>21,.0f}'
              f'{r["python_can_read_fps"] / r["log2bag_fps"]:>7.1f}x  '
              + ('met' if r['met'] else 'NOT met'))
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump({'log2bag': rows}, stream, indent=2)


if __name__ == '__main__':
    main()
