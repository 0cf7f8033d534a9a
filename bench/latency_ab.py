# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Latency and heartbeat before against after, every sample pooled over many turns.

``compare.py`` takes the p99 of each 20 s run (about 1000 samples, so its 10 worst) and
reports the median over rounds: on this 2-core machine one run's p99 moves between 1.2 and
6.5 ms. Here each turn runs ``run.latency_run`` of the before tree, of the after tree and of
the reference pipeline (python-can recv -> rclpy publish, from the after tree), the order
rotating every round, and every latency sample of a side goes into one pool. The table gives
the pooled p50, p99, p99.9 and max of each side, how many samples were slower than 2 and 5
ms, and the p99 of each turn, so a tail that one noisy turn made is told apart from one that
every turn shows. ``--scenario heartbeat-idle`` / ``heartbeat-load`` does the same with
``run.heartbeat_run`` (the AMS heartbeat's |period - 50 ms| of the suite's ``heartbeat``
scenario, idle or under the simulators' load with a waiting service call; no reference).

Run (after a ``git worktree`` of the before commit with its own .venv, see README.md):
``.venv/bin/python bench/latency_ab.py --before /tmp/base --rounds 6 [--seconds 30]
[--background 1000] [--json bench/latency_ab.json]``; ``--from-json A.json B.json`` pools
the samples of earlier runs into one table. Each side runs its own tree's
``bench/run.py`` with its own .venv (so its own installed bridge), on a ROS domain of its own.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402  (network rule)

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# What each side runs, in its own tree: one latency_run (samples in ms), or one
# heartbeat_run (|period - 50 ms| of each period), as JSON.
DRIVER = """
import json, sys
sys.path.insert(0, sys.argv[1] + '/bench')
import run
if sys.argv[2].startswith('heartbeat'):
    periods = run.heartbeat_run(float(sys.argv[3]), sys.argv[2] == 'heartbeat-load')
    samples = [abs(p - 50.0) for p in periods]
else:
    samples = run.latency_run(sys.argv[2], float(sys.argv[3]), 50.0, float(sys.argv[4]))
with open(sys.argv[5], 'w', encoding='utf-8') as stream:
    json.dump(samples, stream)
"""


def turn(tree: str, pipeline: str, seconds: float, background: float, domain: str) -> list:
    """Run one latency_run in tree (its .venv); return its samples in ms."""
    env = harness.env()
    env['ROS_DOMAIN_ID'] = domain
    with tempfile.TemporaryDirectory() as work:
        out = os.path.join(work, 'samples.json')
        subprocess.run([os.path.join(tree, '.venv', 'bin', 'python'), '-c', DRIVER, tree,
                        pipeline, str(seconds), str(background), out], env=env, check=True,
                       cwd=tree, timeout=seconds + 120, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        with open(out, encoding='utf-8') as stream:
            return json.load(stream)


def summary(pool: list[float], per_turn: list[float]) -> dict:
    """Return the pooled figures of one side."""
    q = harness.percentile
    return {'samples': len(pool), 'p50': q(pool, 0.5), 'p99': q(pool, 0.99),
            'p99.9': q(pool, 0.999), 'max': max(pool, default=float('nan')),
            'over_2ms': sum(v > 2.0 for v in pool), 'over_5ms': sum(v > 5.0 for v in pool),
            'over_25ms': sum(v > 25.0 for v in pool),  # a heartbeat slot late (or after one)
            'turn_p99': per_turn, 'median_turn_p99': statistics.median(per_turn)}


def report(pools: dict[str, list[float]], turns: dict[str, list[float]], title: str) -> dict:
    """Print the table of the pooled sides; return it."""
    table = {name: summary(pools[name], turns[name]) for name in pools}
    print(f'\n{title}')
    print('| side | samples | p50 | p99 | p99.9 | max | >2 ms | >5 ms | >25 ms | median of '
          'the turns\' p99 | p99 of each turn |')
    print('|---|---|---|---|---|---|---|---|---|---|---|')
    for name, s in table.items():
        print(f"| {name} | {s['samples']} | {s['p50']:.2f} | {s['p99']:.2f} | "
              f"{s['p99.9']:.2f} | {s['max']:.2f} | {s['over_2ms']} | {s['over_5ms']} | "
              f"{s.get('over_25ms', '')} | {s['median_turn_p99']:.2f} | "
              + ', '.join(f'{v:.2f}' for v in s['turn_p99']) + ' |')
    # The same round's turns ran within two minutes of each other: compare them in pairs.
    wins = sum(a < b for a, b in zip(turns['after'], turns['before']))
    print(f'after faster than before (p99) in {wins} of {len(turns["after"])} rounds')
    return table


def main() -> None:
    """Run the turns and print one table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--before', help='the before tree (with its .venv)')
    parser.add_argument('--after', default=HERE, help='the after tree (default: this one)')
    parser.add_argument('--rounds', type=int, default=6)
    parser.add_argument('--seconds', type=float, default=30.0, help='s of frames per turn')
    parser.add_argument('--background', type=float, default=1000.0,
                        help='other frames/s beside the 50 tagged IVT-S frames/s')
    parser.add_argument('--scenario', default='latency',
                        choices=('latency', 'heartbeat-idle', 'heartbeat-load'))
    parser.add_argument('--json', default=None, help='write every sample here')
    parser.add_argument('--from-json', nargs='+', default=None, metavar='FILE',
                        help='no runs: pool the samples of earlier --json files')
    args = parser.parse_args()
    if args.from_json:
        pools: dict[str, list[float]] = {}
        turns: dict[str, list[float]] = {}
        for path in args.from_json:
            with open(path, encoding='utf-8') as stream:
                saved = json.load(stream)
            for name, table in saved['table'].items():
                pools.setdefault(name, []).extend(saved['samples'][name])
                turns.setdefault(name, []).extend(table['turn_p99'])
        table = report(pools, turns,
                       f'latency, samples pooled from {len(args.from_json)} file(s) (ms)')
        if args.json:  # the pooled table only: the samples stay in the files given
            with open(args.json, 'w', encoding='utf-8') as stream:
                json.dump({'meta': {'from_json': args.from_json}, 'table': table}, stream,
                          indent=1)
        return
    if not args.before:
        parser.error('--before is needed (or --from-json)')
    what = 'bridge' if args.scenario == 'latency' else args.scenario
    sides = {'before': (args.before, what, '36'), 'after': (args.after, what, '37')}
    if args.scenario == 'latency':
        sides['reference'] = (args.after, 'reference', '38')
    pools: dict[str, list[float]] = {name: [] for name in sides}
    turns: dict[str, list[float]] = {name: [] for name in sides}
    order = list(sides)
    for r in range(args.rounds):
        k = r % len(order)
        for name in order[k:] + order[:k]:  # each side goes first in turn
            tree, pipeline, domain = sides[name]
            got = turn(tree, pipeline, args.seconds, args.background, domain)
            pools[name] += got
            turns[name].append(round(harness.percentile(got, 0.99), 2))
            print(f'round {r + 1} {name}: p99 {turns[name][-1]:.2f} ms ({len(got)} samples)',
                  flush=True)
    title = (f'latency, {args.background:g} other frames/s' if args.scenario == 'latency'
             else f'{args.scenario}: |period - 50 ms|')
    table = report(pools, turns, f'{title}, {args.rounds} rounds of {args.seconds:g} s, '
                   'samples pooled (ms)')
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump({'meta': vars(args), 'table': table, 'samples': pools}, stream)


if __name__ == '__main__':
    main()
