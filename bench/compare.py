# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Before against after: two checkouts' benchmark figures, measured interleaved.

    .venv/bin/python bench/compare.py --before /path/to/base [--after .] [--rounds 3]
        [--only cpu_slcan,cpu_virtual,latency,heartbeat,decode,own_path]
        [--quick]
        [--before-domain 35 --after-domain 34] [--json bench/compare.json]

One run of each side on a shared machine swings by more than most changes (a heartbeat p99
of 50 ms one run, 11 ms the next), so this runs both sides in turns in the same time
window: for each round, for each scenario, one side then the other, the side that goes
first alternating from round to round (so a drift in the machine's load hits both alike).
Each side runs its own tree's suite with its own environment: ``<tree>/.venv/bin/python
<tree>/bench/run.py --only <scenario>`` (the installed bridge of that tree), or
``<tree>/bench/bench_decode.py`` for ``decode`` (each codec against cantools in the same
process), ``<tree>/bench/bench_own_path.py`` for ``own_path`` (the bridge's own CPU per
frame, in one process, python-can left out). Each tree needs its own ``.venv`` with the
package installed editable from it.

The table gives, per figure, each side's median over the rounds with its [min..max], the
change (after median / before median), and where the figure has an in-run reference (a
bare python-can loop or pipeline on the same bus and frames, cantools for decoding) the
same for the ratio to that reference, which cancels much of the machine's noise. The
``spread`` column says whether the two sides' ranges overlap: ``after worse`` or ``after
better`` only when every round of one side beats every round of the other.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT = 'cpu_slcan,cpu_virtual,latency,heartbeat,decode'
HIGHER_IS_BETTER = {'fr/s', 'f/s'}


def run_suite(tree: str, scenario: str, quick: bool, domain: str | None) -> list[dict]:
    """Run one scenario of one tree's suite; return its rows (run.py's JSON schema)."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    if domain:
        env['ROS_DOMAIN_ID'] = domain
    python = os.path.join(tree, '.venv', 'bin', 'python')
    if scenario == 'decode':
        out = subprocess.run([python, os.path.join(tree, 'bench', 'bench_decode.py')]
                             + (['--seconds', '20'] if quick else []),
                             env=env, cwd=tree, check=True, capture_output=True, text=True,
                             timeout=900).stdout
        return decode_rows(out)
    if scenario == 'own_path':
        out = subprocess.run([python, os.path.join(tree, 'bench', 'bench_own_path.py')]
                             + (['--seconds', '10', '--paced', '5'] if quick else []),
                             env=env, cwd=tree, check=True, capture_output=True, text=True,
                             timeout=900).stdout
        return own_path_rows(out)
    with tempfile.TemporaryDirectory() as work:
        path = os.path.join(work, 'r.json')
        subprocess.run([python, os.path.join(tree, 'bench', 'run.py'), '--only', scenario,
                        '--json', path] + (['--quick'] if quick else []),
                       env=env, cwd=tree, check=True, stdout=subprocess.DEVNULL,
                       timeout=1800)
        with open(path, encoding='utf-8') as stream:
            return heartbeat_rows(json.load(stream)['rows'])


def decode_rows(out: str) -> list[dict]:
    """Turn bench_decode.py's table into rows: codec frames/s beside cantools'."""
    rows = []
    for line in out.splitlines():
        m = re.match(r'(\w+)\s+(\d+)\s+([\d,]+)\s+([\d,]+)\s+[\d.]+x', line)
        if m:
            ours, bare = (float(m.group(i).replace(',', '')) for i in (3, 4))
            rows.append({'scenario': 'decode', 'figure': f'{m.group(1)} codec.decode',
                         'bridge': ours, 'reference': bare, 'ratio': ours / bare,
                         'unit': 'f/s'})
    if not rows:
        raise RuntimeError(f'no rows in bench_decode.py output:\n{out}')
    return rows


def own_path_rows(out: str) -> list[dict]:
    """Turn bench_own_path.py's lines into rows (CPU us per frame, periodic thread)."""
    rows = []
    for figure, pattern, unit in (
            ('tight loop, best pass', r'tight loop:\s+([\d.]+) us/frame best', 'us'),
            ('tight loop, median pass', r'best,\s+([\d.]+) median', 'us'),
            ('paced at the real rate', r'own path, paced:\s+([\d.]+) us/frame', 'us'),
            ('periodic thread', r'periodic thread:\s+([\d.]+) us/s', 'us/s')):
        m = re.search(pattern, out)
        if not m:
            raise RuntimeError(f'no {figure!r} in bench_own_path.py output:\n{out}')
        rows.append({'scenario': 'own path (in process)', 'figure': figure,
                     'bridge': float(m.group(1)), 'reference': None, 'ratio': None,
                     'unit': unit})
    return rows


def heartbeat_rows(rows: list[dict]) -> list[dict]:
    """Add the heartbeat's mean period, max error and missed slots (from its note) as rows."""
    out = []
    for r in rows:
        out.append(r)
        if not r['scenario'].startswith('heartbeat'):
            continue
        for name, pattern, unit in (('mean period', r'mean ([\d.]+) ms', 'ms'),
                                    ('max |period-50ms|', r'max ([\d.]+) ms', 'ms'),
                                    ('missed slots (> 75 ms)', r'missed (\d+)', 'slots')):
            m = re.search(pattern, r.get('note', ''))
            if m:
                out.append({'scenario': r['scenario'], 'figure': name,
                            'bridge': float(m.group(1)), 'reference': None, 'ratio': None,
                            'unit': unit})
    return out


def key(rows: list[dict]) -> list[tuple[str, int]]:
    """Key each row by scenario and its place in it (figure texts carry sample counts)."""
    seen: dict[str, int] = {}
    keys = []
    for r in rows:
        seen[r['scenario']] = seen.get(r['scenario'], -1) + 1
        keys.append((r['scenario'], seen[r['scenario']]))
    return keys


def label(figure: str) -> str:
    """Return a figure's text without its sample counts."""
    return re.sub(r'\s*\((\d+|median)[^)]*\)', '', figure).strip()


def spread(before: list[float], after: list[float], unit: str) -> str:
    """Say whether the two sides' ranges are apart, and which way is worse."""
    higher = unit in HIGHER_IS_BETTER
    if min(after) > max(before):
        return 'after better' if higher else 'after worse'
    if max(after) < min(before):
        return 'after worse' if higher else 'after better'
    return 'overlap'


def summary(values: list[float]) -> dict:
    """Median, min and max of a list."""
    return {'median': statistics.median(values), 'min': min(values), 'max': max(values),
            'values': values}


def table(runs: dict[str, dict[str, list[list[dict]]]]) -> list[dict]:
    """Collect, per figure, both sides' values over the rounds."""
    lines = []
    for scenario in runs['after']:
        if not runs['after'][scenario]:
            continue
        first = runs['after'][scenario][0]
        for place, (k, row) in enumerate(zip(key(first), first)):
            sides = {}
            for side in ('before', 'after'):
                found = [dict(zip(key(rows), rows)).get(k) for rows in runs[side][scenario]]
                found = [r for r in found if r is not None]
                sides[side] = found
            if not sides['before'] or not sides['after']:
                continue
            line = {'scenario': row['scenario'], 'figure': label(row['figure']),
                    'unit': row['unit'], 'rounds': [len(sides['before']), len(sides['after'])]}
            for what in ('bridge', 'ratio'):
                b = [r[what] for r in sides['before'] if r.get(what) is not None]
                a = [r[what] for r in sides['after'] if r.get(what) is not None]
                if b and a:
                    unit = row['unit'] if what == 'bridge' else ('f/s' if row['unit'] == 'f/s'
                                                                 or row['unit'] == 'fr/s'
                                                                 else 'x')
                    line[what] = {'before': summary(b), 'after': summary(a),
                                  'change': (statistics.median(a) / statistics.median(b)
                                             if statistics.median(b) else None),
                                  'spread': spread(b, a, unit)}
            lines.append(line)
    return lines


def fmt(s: dict) -> str:
    """Format a side as 'median [min..max]'."""
    def n(v: float) -> str:
        return f'{v:,.0f}' if abs(v) >= 1000 else f'{v:.3g}' if abs(v) < 10 else f'{v:.1f}'
    return f"{n(s['median'])} [{n(s['min'])}..{n(s['max'])}]"


def markdown(lines: list[dict], meta: dict) -> str:
    """Return the table as Markdown."""
    out = [f"Taken {meta['date']}, at least {meta['rounds']} interleaved rounds per side"
           f"{' (--quick)' if meta['quick'] else ''}; before = {meta['before_commit']}, "
           f"after = {meta['after_commit']}. Each cell: median [min..max] over the rounds.",
           '', '| scenario | figure | rounds | unit | before | after | after/before | spread '
           '| ratio to reference: before | after | spread |',
           '|---|---|---|---|---|---|---|---|---|---|---|']
    for ln in lines:
        b = ln['bridge']
        cells = [ln['scenario'], ln['figure'], str(min(ln['rounds'])), ln['unit'],
                 fmt(b['before']), fmt(b['after']),
                 '' if b['change'] is None else f"{b['change']:.2f}", b['spread']]
        r = ln.get('ratio')
        cells += ([fmt(r['before']), fmt(r['after']), r['spread']] if r else ['', '', ''])
        out.append('| ' + ' | '.join(c.replace('|', '\\|') for c in cells) + ' |')
    return '\n'.join(out)


def commit(tree: str) -> str:
    """Return the short commit of a tree (and '+dirty' if it has changes)."""
    try:
        head = subprocess.run(['git', '-C', tree, 'rev-parse', '--short', 'HEAD'],
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(['git', '-C', tree, 'status', '--porcelain', '--',
                                'ams_can_bridge'], capture_output=True, text=True).stdout
        return head + ('+dirty' if dirty.strip() else '')
    except (OSError, subprocess.CalledProcessError):
        return '?'


def save(args: argparse.Namespace, trees: dict, runs: dict, scenarios: list[str],
         started: float) -> tuple[dict, list[dict]]:
    """Write the JSON of the runs so far; return its meta and table."""
    done = min(len(r) for side in runs.values() for r in side.values())
    meta = {'date': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
            'rounds': done, 'quick': args.quick,
            'before_commit': commit(trees['before']), 'after_commit': commit(trees['after']),
            'duration_s': round(time.monotonic() - started, 1), 'scenarios': scenarios}
    lines = table(runs)
    with open(args.json, 'w', encoding='utf-8') as stream:
        json.dump({'meta': meta, 'table': lines, 'runs': runs}, stream, indent=1)
    return meta, lines


def merge(paths: list[str]) -> dict:
    """Pool the rounds of earlier comparisons (same trees); recompute the table."""
    runs: dict = {'before': {}, 'after': {}}
    metas = []
    for path in paths:
        with open(path, encoding='utf-8') as stream:
            saved = json.load(stream)
        metas.append(saved['meta'])
        for side in runs:
            for scenario, rounds in saved['runs'][side].items():
                runs[side].setdefault(scenario, []).extend(rounds)
    meta = dict(metas[-1])
    meta['rounds'] = min(len(r) for side in runs.values() for r in side.values())
    meta['duration_s'] = sum(m['duration_s'] for m in metas)
    meta['scenarios'] = list(runs['after'])
    meta['pooled'] = paths
    return {'meta': meta, 'table': table(runs), 'runs': runs}


def main() -> None:
    """Run both trees interleaved; print the table; write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--before', help='tree of the base commit (.venv in it); needed to run')
    parser.add_argument('--after', default=os.path.dirname(HERE), help='tree to compare')
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--only', default=DEFAULT, help=f'scenarios (default {DEFAULT}); '
                        "run.py's names, decode (bench_decode.py) and own_path "
                        '(bench_own_path.py)')
    parser.add_argument('--quick', action='store_true', help="run.py's shorter runs")
    parser.add_argument('--before-domain', default=None, help='ROS_DOMAIN_ID of the before runs')
    parser.add_argument('--after-domain', default=None, help='ROS_DOMAIN_ID of the after runs')
    parser.add_argument('--json', default=os.path.join(HERE, 'compare.json'))
    parser.add_argument('--from-json', nargs='*', metavar='FILE', default=None,
                        help='no run: print the table of earlier --json files (their rounds '
                        'pooled, e.g. extra rounds of one scenario) and write it to --json')
    args = parser.parse_args()
    if args.from_json is not None:
        merged = merge(args.from_json or [args.json])
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump(merged, stream, indent=1)
        print(markdown(merged['table'], merged['meta']))
        return
    if not args.before:
        parser.error('--before is needed to run (only --from-json works without it)')
    trees = {'before': os.path.abspath(args.before), 'after': os.path.abspath(args.after)}
    domains = {'before': args.before_domain, 'after': args.after_domain}
    scenarios = [s for s in args.only.split(',') if s]
    runs: dict = {side: {s: [] for s in scenarios} for side in trees}
    started = time.monotonic()
    for n in range(args.rounds):
        order = ('before', 'after') if n % 2 == 0 else ('after', 'before')
        for scenario in scenarios:
            for side in order:
                t0 = time.monotonic()
                rows = run_suite(trees[side], scenario, args.quick, domains[side])
                runs[side][scenario].append(rows)
                print(f'round {n + 1}/{args.rounds} {scenario:<12} {side:<6} '
                      f'{time.monotonic() - t0:5.0f} s', flush=True)
                # written after every run, so an interrupted comparison keeps its rounds
                meta, lines = save(args, trees, runs, scenarios, started)
    print(markdown(lines, meta))
    print(f'wrote {args.json} ({meta["duration_s"]} s)')


if __name__ == '__main__':
    sys.exit(main())
