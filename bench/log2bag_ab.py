# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag before against after: each tree's bench_log2bag.py in turns, in one time window.

Each run converts the simulated car mix (``--seconds`` of bus per log) and reads it with
python-can in the same process, so every run carries its own reference; the side that goes
first alternates from round to round. The before tree needs no venv of its own: it is put
first on PYTHONPATH (``git archive <commit> | tar -x -C DIR``).
Run: ``.venv/bin/python bench/log2bag_ab.py --before DIR [--rounds 3] [--seconds 120,600]``.
Prints one Markdown table (median [min..max] per figure) and writes ``--json`` if given.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
AFTER = os.path.dirname(HERE)


def one(tree: str, seconds: float, formats: str) -> list[dict]:
    """Run tree's bench_log2bag.py once; return its rows."""
    with tempfile.NamedTemporaryFile(suffix='.json') as out:
        env = dict(os.environ, PYTHONPATH=tree)
        subprocess.run([sys.executable, os.path.join(tree, 'bench', 'bench_log2bag.py'),
                        '--seconds', str(seconds), '--formats', formats, '--json', out.name],
                       env=env, check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, cwd=tree)
        with open(out.name, encoding='utf-8') as stream:
            return json.load(stream)['log2bag']


def cell(values: list[float], fmt: str = '{:,.0f}') -> str:
    """Return 'median [min..max]'."""
    return (fmt.format(statistics.median(values)) + ' [' + fmt.format(min(values)) + '..'
            + fmt.format(max(values)) + ']')


def main() -> None:
    """Run the rounds and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--before', required=True, help='the before tree (package root)')
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--seconds', default='120,600',
                        help='simulated seconds per log, comma-separated (one log each)')
    parser.add_argument('--formats', default='log,blf')
    parser.add_argument('--json', default='')
    args = parser.parse_args()
    sides = {'before': os.path.abspath(args.before), 'after': AFTER}
    runs: dict = {}
    for k in range(args.rounds):
        order = ['before', 'after'] if k % 2 == 0 else ['after', 'before']
        for seconds in [float(s) for s in args.seconds.split(',')]:
            for side in order:
                for row in one(sides[side], seconds, args.formats):
                    key = (seconds, row['format'])
                    runs.setdefault(key, {}).setdefault(side, []).append(row)
                print(f'round {k + 1}: {seconds:g} s {side} done', file=sys.stderr, flush=True)
    print('| log | frames | side | log2bag frames/s | python-can read frames/s '
          '| log2bag / read |')
    print('|---|---|---|---|---|---|')
    for (seconds, fmt), by_side in sorted(runs.items()):
        for side in ('before', 'after'):
            rows = by_side[side]
            ratio = [r['log2bag_fps'] / r['python_can_read_fps'] for r in rows]
            print(f'| {seconds:g} s .{fmt} | {rows[0]["frames"]:,} | {side} | '
                  f'{cell([r["log2bag_fps"] for r in rows])} | '
                  f'{cell([r["python_can_read_fps"] for r in rows])} | '
                  f'{cell(ratio, "{:.3f}")}x |')
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump({'sides': sides, 'runs': {f'{s:g}s.{f}': v
                                                for (s, f), v in runs.items()}},
                      stream, indent=1)


if __name__ == '__main__':
    main()
