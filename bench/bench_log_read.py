# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Reading a log: python-can's bare read beside log2bag's own readers, CPU per frame.

The log is ``bench_log2bag.py``'s car mix (AMS with 5 banks + IVT-S, EVMS3 with 8 BMS12,
BMS16 + SMA) over ``--seconds`` of simulated time, written once per format. Per format,
three readings of the same file, each the min of ``--passes`` passes (``time.process_time``,
open and read to the end), in one run: python-can's ``can.LogReader`` (the reference),
``LogFrames.frames()`` (the tuples log2bag's converter takes: issue 39's own readers) and
``LogFrames`` iterated as before (``can.Message`` objects, bad entries counted).
Run: ``.venv/bin/python bench/bench_log_read.py [--seconds 600] [--formats log,blf]``.
"""
import argparse
import json
import os
import shutil
import tempfile
import time
from typing import Callable

import can

from ams_can_bridge.offline.log_frames import LogFrames
from ams_can_bridge.sim.recording import write_log
from bench_log2bag import simulators


def python_can(path: str) -> int:
    """Read the log with python-can alone; return the frames."""
    reader = can.LogReader(path)
    count = sum(1 for _ in reader)
    reader.stop()
    return count


def own_tuples(path: str) -> int:
    """Read the log as log2bag does (``LogFrames.frames()``); return the frames."""
    frames = LogFrames(path)
    count = sum(1 for _ in frames.frames())
    frames.close()
    return count


def log_frames(path: str) -> int:
    """Iterate ``LogFrames`` (python-can's messages, checked); return the frames."""
    frames = LogFrames(path)
    count = sum(1 for _ in frames)
    frames.close()
    return count


READS: dict[str, Callable[[str], int]] = {
    'python-can': python_can, 'own tuples': own_tuples, 'LogFrames': log_frames}


def best(read: Callable[[str], int], path: str, passes: int) -> tuple[int, float]:
    """Return (frames, the least CPU seconds of the passes)."""
    least = float('inf')
    count = 0
    for _ in range(passes):
        start = time.process_time()
        count = read(path)
        least = min(least, time.process_time() - start)
    return count, least


def main() -> None:
    """Write the log in each format, read it each way, print us per frame."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=600.0)
    parser.add_argument('--formats', default='log,blf')
    parser.add_argument('--passes', type=int, default=3)
    parser.add_argument('--json', default='', help='also write the figures here')
    args = parser.parse_args()
    work = tempfile.mkdtemp(prefix='bench_log_read_')
    rows = []
    try:
        for fmt in args.formats.split(','):
            path = os.path.join(work, f'bus.{fmt}')
            written = write_log(path, simulators(), args.seconds)
            row: dict = {'format': fmt, 'frames': written}
            for name, read in READS.items():
                count, seconds = best(read, path, args.passes)
                assert count == written, (fmt, name, count, written)
                row[name] = seconds / count * 1e6
            rows.append(row)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f'reading {args.seconds:g} s of the car mix, us of CPU per frame, min of '
          f'{args.passes} passes (load average {os.getloadavg()[0]:.2f})')
    print(f'{"format":<7}{"frames":>9}' + ''.join(f'{n:>13}' for n in READS)
          + f'{"own/python-can":>16}')
    for r in rows:
        print(f'{r["format"]:<7}{r["frames"]:>9}' + ''.join(f'{r[n]:>13.2f}' for n in READS)
              + f'{r["own tuples"] / r["python-can"]:>15.2f}x')
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump({'log_read': rows}, stream, indent=2)


if __name__ == '__main__':
    main()
