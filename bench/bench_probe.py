"""
probe benchmark: frames per second probe reads and recognises, beside log2bag on the same log.

The log is bench_log2bag's simulated mix (AMS with 5 banks + IVT-S, EVMS3 with 8 BMS12
modules, BMS16 + SMA) over ``--seconds`` of simulated time, per format. In one run, passes
alternate: probe (``sources.read_log`` + ``recognise`` + the params file's text, as ``probe
LOG --output`` does) and log2bag (``convert``) on the same file, and python-can's bare read
as the floor. The median pass of each counts. Target: probe at least as fast as log2bag.
Run: ``./dev bench --only probe`` or ``.venv/bin/python bench/bench_probe.py``.
"""
import argparse
import json
import os
import shutil
import statistics
import tempfile
import time

from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.probe.output import render
from ams_can_bridge.probe.recognise import recognise
from ams_can_bridge.probe.sources import read_log
from ams_can_bridge.sim.recording import write_log
from bench_log2bag import bare_read, PARAMETERS, simulators


def probe_pass(log: str) -> tuple[int, float, int]:
    """Return (frames, seconds, devices written) of one probe pass over the log."""
    start = time.perf_counter()
    traffic = read_log(log)
    findings = recognise(traffic)
    render(findings, [], log)
    return traffic.frames, time.perf_counter() - start, len(findings.written)


def log2bag_pass(log: str, work: str, n: int) -> tuple[int, float]:
    """Return (frames, seconds) of one log2bag conversion of the log."""
    bag = os.path.join(work, f'bag_{n}')
    start = time.perf_counter()
    summary = convert(log, bag, PARAMETERS)
    seconds = time.perf_counter() - start
    shutil.rmtree(bag, ignore_errors=True)
    return summary.frames_read, seconds


def measure(seconds: float, formats, passes: int = 3) -> list[dict]:
    """Measure probe and log2bag on one simulated log per format, passes alternating."""
    work = tempfile.mkdtemp(prefix='bench_probe_')
    rows = []
    try:
        for fmt in formats:
            log = os.path.join(work, f'bus.{fmt}')
            frames = write_log(log, simulators(), seconds)
            probe_s, log2bag_s, read_s = [], [], []
            devices = 0
            for n in range(passes):
                order = ('probe', 'log2bag') if n % 2 == 0 else ('log2bag', 'probe')
                for what in order:
                    if what == 'probe':
                        count, took, devices = probe_pass(log)
                        probe_s.append(took)
                    else:
                        count, took = log2bag_pass(log, work, n)
                        log2bag_s.append(took)
                    assert count == frames, (what, count, frames)
                read_s.append(bare_read(log)[1])
            probe_fps = frames / statistics.median(probe_s)
            log2bag_fps = frames / statistics.median(log2bag_s)
            rows.append({'format': fmt, 'frames': frames, 'devices_written': devices,
                         'probe_fps': probe_fps, 'log2bag_fps': log2bag_fps,
                         'python_can_read_fps': frames / statistics.median(read_s),
                         'passes': passes, 'met': probe_fps >= log2bag_fps})
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return rows


def main() -> None:
    """Measure each format and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=60.0,
                        help='simulated seconds of bus traffic in the log')
    parser.add_argument('--formats', default='log,blf')
    parser.add_argument('--passes', type=int, default=3)
    parser.add_argument('--json', default='', help='also write the figures here')
    args, _ = parser.parse_known_args()
    rows = measure(args.seconds, args.formats.split(','), args.passes)
    print(f'probe and log2bag, {args.seconds:g} s of simulated bus per format, median of '
          f'{args.passes} alternating passes (target: probe >= log2bag)')
    print(f'{"format":<7}{"frames":>9}{"probe fps":>12}{"log2bag fps":>14}'
          f'{"python-can read fps":>21}{"probe/log2bag":>15}  target')
    for r in rows:
        print(f'{r["format"]:<7}{r["frames"]:>9}{r["probe_fps"]:>12,.0f}'
              f'{r["log2bag_fps"]:>14,.0f}{r["python_can_read_fps"]:>21,.0f}'
              f'{r["probe_fps"] / r["log2bag_fps"]:>14.1f}x  '
              + ('met' if r['met'] else 'NOT met'))
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump({'probe': rows}, stream, indent=2)


if __name__ == '__main__':
    main()
