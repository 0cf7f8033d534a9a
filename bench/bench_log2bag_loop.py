# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's loop taken apart: the devices, then + snapshots, + the bag, + the periodic work.

The frames of a car-mix log (``bench_log2bag``'s, ``--seconds`` of it) are read beforehand,
then fed four ways to fresh converters, CPU per frame (``time.process_time``, min of
``--passes``): the devices' ``handle_frame`` alone; the engine's ``on_frame`` with the sink
muted (decode, state, snapshots); the same writing the bag; ``Converter.frame`` (the whole
loop, /diagnostics and the watch on the log's time). The differences are what each part
costs. ``--before DIR`` runs a second tree (``git archive <commit> | tar -x -C DIR``) in
turns with this one, the order alternating, and prints both with their ratio.
Run: ``.venv/bin/python bench/bench_log2bag_loop.py [--seconds 600] [--before DIR]``.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
PARTS = ('handle', '+snapshot', '+write', 'whole loop')


def measure(log: str, passes: int) -> dict[str, float]:
    """Return us of CPU per frame of each part, for the tree this process imports."""
    import can
    from bench_log2bag import PARAMETERS
    from ams_can_bridge.offline.converter import Converter
    from ams_can_bridge.offline.log2bag import open_bag
    frames = [(m.arbitration_id, bytes(m.data), m.is_extended_id, m.timestamp)
              for m in can.LogReader(log)]
    work = tempfile.mkdtemp(prefix='bench_loop_')
    best = dict.fromkeys(PARTS, float('inf'))
    try:
        for k in range(passes):
            for part in PARTS:
                bag = os.path.join(work, f'bag{k}{PARTS.index(part)}')
                converter = Converter(PARAMETERS, None, 'replay:bench')
                converter.bag = open_bag(bag, 'mcap')
                converter.sink.enabled = part == '+write'
                call = (converter.devices.handle_frame if part == 'handle'
                        else converter.engine.on_frame)
                start = time.process_time()
                if part == 'whole loop':
                    frame = converter.frame
                    for arbitration_id, data, extended, stamp in frames:
                        frame(arbitration_id, data, extended, stamp, True)
                else:
                    for arbitration_id, data, extended, stamp in frames:
                        converter.now = stamp
                        call(arbitration_id, data, extended, stamp)
                cost = (time.process_time() - start) / len(frames) * 1e6
                best[part] = min(best[part], cost)
                converter.bag.close()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return best


def main() -> None:
    """Measure this tree (and --before's in turns); print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=600.0)
    parser.add_argument('--passes', type=int, default=3)
    parser.add_argument('--rounds', type=int, default=2, help='turns of each tree (--before)')
    parser.add_argument('--before', default='', help='a tree to measure in turns with this one')
    parser.add_argument('--log', default='', help=argparse.SUPPRESS)  # a child's log
    args = parser.parse_args()
    if args.log:  # a child: one tree, one line per part
        for part, cost in measure(args.log, args.passes).items():
            print(f'{part}\t{cost:.3f}')
        return
    from bench_log2bag import simulators
    from ams_can_bridge.sim.recording import write_log
    work = tempfile.mkdtemp(prefix='bench_loop_log_')
    try:
        log = os.path.join(work, 'bus.log')
        frames = write_log(log, simulators(), args.seconds)
        trees = {'this': os.path.dirname(HERE)}
        if args.before:
            trees = {'before': os.path.abspath(args.before), **trees}
        runs: dict[str, dict[str, list[float]]] = {side: {p: [] for p in PARTS} for side in trees}
        for k in range(args.rounds if args.before else 1):
            order = list(trees) if k % 2 == 0 else list(reversed(trees))
            for side in order:
                tree = trees[side]
                out = subprocess.run(
                    [sys.executable, os.path.join(tree, 'bench', 'bench_log2bag_loop.py'),
                     '--log', log, '--passes', str(args.passes)],
                    env=dict(os.environ, PYTHONPATH=tree), cwd=tree, check=True,
                    capture_output=True, text=True).stdout
                for line in out.splitlines():
                    part, cost = line.split('\t')
                    runs[side][part].append(float(cost))
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f'log2bag loop, {args.seconds:g} s car mix ({frames:,} frames), us of CPU per frame, '
          f'min over {args.passes} passes' + (f' and {args.rounds} rounds' if args.before else ''))
    print(f'{"part":<12}' + ''.join(f'{side:>10}' for side in trees)
          + ('     ratio' if args.before else ''))
    for part in PARTS:
        cells = [min(runs[side][part]) for side in trees]
        ratio = f'{cells[1] / cells[0]:>10.3f}' if args.before else ''
        print(f'{part:<12}' + ''.join(f'{c:>10.2f}' for c in cells) + ratio)


if __name__ == '__main__':
    main()
