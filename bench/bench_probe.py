# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe benchmark: frames per second probe reads and recognises, beside log2bag on the same log.

The log is bench_log2bag's simulated mix (AMS with 5 banks + IVT-S, EVMS3 with 8 BMS12
modules, BMS16 + SMA) over ``--seconds`` of simulated time, per format, then a .log of each
shipped dbc profile as ``simulator --profile`` plays it (foxBMS 2, Orion BMS 2: there probe
also feeds the frames through the dbc device to judge the values). In one run, passes
alternate: probe (``sources.read_log`` + ``recognise`` + the params file's text, as ``probe
LOG --output`` does) and log2bag (``convert``) on the same file, and python-can's bare read
as the floor. The median pass of each counts. Target: probe at least as fast as log2bag.
Run: ``./dev bench --only probe`` or ``.venv/bin/python bench/bench_probe.py``.
"""
import argparse
import os
import shutil
import statistics
import tempfile
import time

from ams_can_bridge.protocols.dbc_profiles import PROFILES
from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.probe.output import render
from ams_can_bridge.probe.recognise import recognise
from ams_can_bridge.probe.sources import read_log
from ams_can_bridge.sim.main import build_devices
from ams_can_bridge.sim.recording import write_log
from bench_log2bag import bare_read, PARAMETERS, simulators


def probe_pass(log: str) -> tuple[int, float, int]:
    """Return (frames, seconds, devices written) of one probe pass over the log."""
    start = time.perf_counter()
    traffic = read_log(log)
    findings = recognise(traffic)
    render(findings, [], log)
    return traffic.frames, time.perf_counter() - start, len(findings.written)


def log2bag_pass(log: str, work: str, n: int, params: dict) -> tuple[int, float]:
    """Return (frames, seconds) of one log2bag conversion of the log."""
    bag = os.path.join(work, f'bag_{n}')
    start = time.perf_counter()
    summary = convert(log, bag, params)
    seconds = time.perf_counter() - start
    shutil.rmtree(bag, ignore_errors=True)
    return summary.frames_read, seconds


def alternate(log: str, work: str, frames: int, passes: int, params: dict = PARAMETERS) -> dict:
    """Time probe and log2bag on one log, passes alternating; the figures of the median."""
    times: dict[str, list[float]] = {'probe': [], 'log2bag': [], 'read': []}
    devices = 0
    for n in range(passes):
        for what in (('probe', 'log2bag') if n % 2 == 0 else ('log2bag', 'probe')):
            if what == 'probe':
                count, took, devices = probe_pass(log)
            else:
                count, took = log2bag_pass(log, work, n, params)
            assert count == frames, (what, count, frames)
            times[what].append(took)
        times['read'].append(bare_read(log)[1])
    fps = {what: frames / statistics.median(t) for what, t in times.items()}
    return {'frames': frames, 'devices_written': devices, 'probe_fps': fps['probe'],
            'log2bag_fps': fps['log2bag'], 'python_can_read_fps': fps['read'],
            'passes': passes, 'met': fps['probe'] >= fps['log2bag']}


def measure(seconds: float, formats, passes: int = 3) -> list[dict]:
    """Measure probe and log2bag on one simulated log per format."""
    rows = []
    with tempfile.TemporaryDirectory(prefix='bench_probe_') as work:
        for fmt in formats:
            log = os.path.join(work, f'bus.{fmt}')
            frames = write_log(log, simulators(), seconds)
            rows.append({'format': fmt, **alternate(log, work, frames, passes)})
    return rows


def measure_profiles(seconds: float, passes: int = 3) -> list[dict]:
    """Measure probe and log2bag on a .log of each shipped dbc profile's simulator."""
    rows = []
    with tempfile.TemporaryDirectory(prefix='bench_probe_') as work:
        for profile in PROFILES:
            log = os.path.join(work, f'{profile}.log')
            frames = write_log(log, build_devices(['dbc'], profile=profile), seconds)
            params = {'devices': ['bms'], 'bms.type': 'dbc', 'bms.profile': profile}
            rows.append({'format': f'log ({profile})',
                         **alternate(log, work, frames, passes, params)})
    return rows


def main() -> None:
    """Measure each format and print one line per format."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=60.0,
                        help='simulated seconds of bus traffic in the log')
    parser.add_argument('--passes', type=int, default=3)
    args, _ = parser.parse_known_args()
    print(f'probe against log2bag, {args.seconds:g} s of simulated bus per format, median of '
          f'{args.passes} alternating passes (target: probe >= log2bag)')
    for r in (measure(args.seconds, ('log', 'blf'), args.passes)
              + measure_profiles(args.seconds, args.passes)):
        verdict = 'met' if r['met'] else 'NOT met'
        print(f'.{r["format"]}: {r["frames"]} frames, {r["devices_written"]} devices; probe '
              f'{r["probe_fps"]:,.0f} frames/s, log2bag {r["log2bag_fps"]:,.0f} '
              f'({r["probe_fps"] / r["log2bag_fps"]:.1f}x), python-can alone '
              f'{r["python_can_read_fps"]:,.0f}: {verdict}')


if __name__ == '__main__':
    main()
