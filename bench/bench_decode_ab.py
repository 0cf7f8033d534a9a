# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Decode benchmark, before against after in ONE process: two checkouts' codecs side by side.

``bench_decode.py`` run twice (once per checkout) swings by up to 2x on a shared machine;
here both codec sets are imported into one process (the package is imported twice from two
source trees) and their passes over the same frames are interleaved, so a load swing hits
both alike; the best pass of each counts.
Run: ``git worktree add /tmp/base <commit>`` (or ``git archive <commit> | tar -x -C /tmp/base``),
then ``.venv/bin/python bench/bench_decode_ab.py --before /tmp/base``.
"""
import argparse
import importlib
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PROTOCOLS = {'ams': 'AmsCodec', 'ivt_s': 'IvtSCodec', 'evms3': 'Evms3Codec',
             'bms16': 'Bms16Codec', 'sma': 'SmaCodec'}


def load(root: str) -> dict:
    """Import the package from one source tree and build its codecs."""
    for name in [m for m in sys.modules if m.split('.')[0] == 'ams_can_bridge']:
        del sys.modules[name]
    sys.path.insert(0, root)
    try:
        return {name: getattr(importlib.import_module(f'ams_can_bridge.protocols.{name}'),
                              cls)() for name, cls in PROTOCOLS.items()}
    finally:
        sys.path.remove(root)


def one_pass(codec, frames) -> float:
    """Return the seconds one pass of codec.decode over the frames takes."""
    decode = codec.decode
    start = time.perf_counter()
    for arbitration_id, data, _extended in frames:
        decode(arbitration_id, data)
    return time.perf_counter() - start


def main() -> None:
    """Measure and print one row per protocol."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--before', required=True, help='source tree of the base commit')
    parser.add_argument('--after', default=str(HERE.parent), help='source tree to compare')
    parser.add_argument('--seconds', type=float, default=60.0, help='simulated time per device')
    parser.add_argument('--passes', type=int, default=40, help='interleaved passes per side')
    args = parser.parse_args()
    before, after = load(args.before), load(args.after)
    sys.path[:0] = [args.after, str(HERE)]
    import bench_decode  # the frame mix of the checkout under test
    mix = bench_decode.frame_mix(args.seconds)
    print(f'{"protocol":8} {"frames":>6} {"before f/s":>12} {"after f/s":>12} {"change":>8}')
    for name, frames in mix.items():
        if not frames:
            continue
        best_before = best_after = float('inf')
        for _ in range(args.passes):
            best_before = min(best_before, one_pass(before[name], frames))
            best_after = min(best_after, one_pass(after[name], frames))
        print(f'{name:8} {len(frames):6d} {len(frames) / best_before:12,.0f} '
              f'{len(frames) / best_after:12,.0f} {best_before / best_after - 1:+8.1%}')
    print(f'best of {args.passes} interleaved passes each; change > 0: after is faster')


if __name__ == '__main__':
    main()
