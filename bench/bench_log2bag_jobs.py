# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag --jobs: a folder of logs converted with 1 job, then with every core, wall time.

The logs are bench_log2bag's car mix (``--seconds`` of simulated bus each, ``--logs`` of
them); each side runs the installed ``log2bag LOGS --output-dir DIR --jobs N`` as a process,
the order alternating over ``--rounds``. Prints the wall time per side and the speed-up.
Run: ``.venv/bin/python bench/bench_log2bag_jobs.py [--logs 4] [--seconds 120]``.
"""
import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import yaml

from bench_log2bag import PARAMETERS, simulators
from ams_can_bridge.offline.log2bag_jobs import default_jobs
from ams_can_bridge.sim.recording import write_log


def params_file(path: str) -> str:
    """Write PARAMETERS as a parameters file (dotted names, as ROS 2 reads them too)."""
    with open(path, 'w', encoding='utf-8') as stream:
        yaml.safe_dump({'/**': {'ros__parameters': PARAMETERS}}, stream)
    return path


def main() -> None:
    """Write the logs, convert them with 1 and with N jobs in turns, print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--logs', type=int, default=4)
    parser.add_argument('--seconds', type=float, default=120.0)
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--jobs', type=int, default=default_jobs())
    args = parser.parse_args()
    work = tempfile.mkdtemp(prefix='bench_jobs_')
    exe = os.path.join(os.path.dirname(sys.executable), 'log2bag')
    try:
        logs = os.path.join(work, 'logs')
        os.mkdir(logs)
        frames = sum(write_log(os.path.join(logs, f'run{k}.log'), simulators(), args.seconds)
                     for k in range(args.logs))
        params = params_file(os.path.join(work, 'params.yaml'))
        times: dict[int, list[float]] = {1: [], args.jobs: []}
        for k in range(args.rounds):
            for jobs in ([1, args.jobs] if k % 2 == 0 else [args.jobs, 1]):
                out = os.path.join(work, f'bags{jobs}')
                shutil.rmtree(out, ignore_errors=True)
                os.mkdir(out)
                start = time.perf_counter()
                subprocess.run([exe, logs, '--output-dir', out, '--params-file', params,
                                '--jobs', str(jobs)], check=True, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
                times[jobs].append(time.perf_counter() - start)
        one, many = statistics.median(times[1]), statistics.median(times[args.jobs])
        print(f'{args.logs} logs x {args.seconds:g} s ({frames:,} frames), {args.rounds} '
              f'rounds, median wall time: --jobs 1 {one:.2f} s ({frames / one:,.0f} frames/s), '
              f'--jobs {args.jobs} {many:.2f} s ({frames / many:,.0f} frames/s): '
              f'{one / many:.2f}x; all: {times}')
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
