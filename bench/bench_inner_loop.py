# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The inner loop's figures: its tests, its time and (``--coverage``) its line coverage.

How many tests ``./dev test -m "not ros and not process"`` runs, in how long, and the line
coverage of the package they reach.

    python bench/bench_inner_loop.py              # time the inner loop, write the figures
    python bench/bench_inner_loop.py --coverage   # the same run under coverage.py
    python bench/bench_inner_loop.py -- --deselect TEST   # pytest arguments of your own

Writes bench/inner_loop.json (``tests``, ``seconds``, ``cores``, ``date``; with --coverage
``coverage_percent`` instead of the time, which coverage slows down). doc/getting_started.md
quotes the time, QUALITY_DECLARATION.md the coverage; test/test_package_doc_figures.py keeps
both quotes equal to this file and fails once the suite has grown or shrunk by more than a
tenth since it was measured: then run this again.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
from pathlib import Path
import re
import subprocess
import sys
import tempfile
import time

ROOT = Path(__file__).resolve().parent.parent
RESULT = ROOT / 'bench' / 'inner_loop.json'
LANE = ['-m', 'not ros and not process', '-q', '-p', 'no:cacheprovider']


def run(coverage: bool, extra: list[str]) -> dict[str, object]:
    """Run the inner loop once; return its figures."""
    with tempfile.TemporaryDirectory() as work:
        data = os.path.join(work, '.coverage')
        head = ([sys.executable, '-m', 'coverage', 'run', f'--data-file={data}',
                 '--source=ams_can_bridge', '-m', 'pytest'] if coverage
                else [sys.executable, '-m', 'pytest'])
        started = time.monotonic()
        done = subprocess.run(head + LANE + extra, cwd=ROOT, capture_output=True, text=True)
        seconds = time.monotonic() - started
        summary = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ''
        passed = re.search(r'(\d+) passed', summary)
        if done.returncode != 0 or passed is None:
            raise SystemExit(f'the inner loop failed: {summary or done.stderr[-2000:]}')
        figures: dict[str, object] = {
            'tests': int(passed.group(1)), 'cores': os.cpu_count(),
            'date': datetime.date.today().isoformat()}
        if coverage:
            report = subprocess.run([sys.executable, '-m', 'coverage', 'report',
                                     f'--data-file={data}', '--format=total'], cwd=ROOT,
                                    capture_output=True, text=True, check=True)
            figures['coverage_percent'] = int(report.stdout.strip())
        else:
            figures['seconds'] = round(seconds)
    return figures


def main(argv: list[str] | None = None) -> int:
    """Measure and merge the figures into bench/inner_loop.json."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--coverage', action='store_true',
                        help='run under coverage.py and record the line coverage')
    parser.add_argument('pytest_args', nargs='*', metavar='-- PYTEST_ARGS',
                        help='more pytest arguments')
    args = parser.parse_args(argv)
    figures = run(args.coverage, args.pytest_args)
    key = 'coverage' if args.coverage else 'time'
    old = json.loads(RESULT.read_text()) if RESULT.exists() else {}
    old[key] = figures
    RESULT.write_text(json.dumps(old, indent=2, sort_keys=True) + '\n')
    print(json.dumps(figures))
    return 0


if __name__ == '__main__':
    sys.exit(main())
