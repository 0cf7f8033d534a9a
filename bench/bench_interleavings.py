# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The interleaving model (test/test_engine_interleavings.py) run for minutes: new sequences, seeded.

    ./dev bench --only interleavings --minutes 30 [--seed N]

Each seed (seed, seed + 1, ...) is one hypothesis run of the state machine: ``PER_SEED``
sequences of up to ``STEPS`` random steps of parameter sets, calls, transitions, toggles,
unplugs and silences against the ROS-free model bridge, the invariants checked after every
step. Prints a line per seed, and for a broken invariant the steps and the seed;
``--seed N --minutes 0`` runs that seed again.
"""
from __future__ import annotations

import io
import os
import sys
import time
import traceback
from contextlib import redirect_stdout

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), 'test'))
STEPS = 60  # steps per sequence at most (the CI lane: test_engine_interleavings.STEPS)
PER_SEED = 20  # sequences per seed


def one(seed: int, steps: int = STEPS) -> str:
    """Run the sequences of ``seed``; '' when every invariant held, else what broke."""
    import hypothesis.core
    from hypothesis import Phase, Verbosity

    import test_engine_interleavings
    hypothesis.core.global_force_seed = seed  # this sequence, again with the same seed
    out = io.StringIO()
    try:
        with redirect_stdout(out):
            test_engine_interleavings.run(
                PER_SEED, steps, derandomize=False, database=None, phases=[Phase.generate],
                verbosity=Verbosity.normal)
    except BaseException as exc:  # an invariant (or anything) broke: report it whole
        if isinstance(exc, KeyboardInterrupt):
            raise
        last = test_engine_interleavings.Interleavings.last_steps
        steps = '\n'.join(f'    {line}' for line in last)
        return (f'{type(exc).__name__}: {exc}\n  the steps of the last sequence run '
                f'(monotonic s):\n{steps}\n{out.getvalue()}\n{traceback.format_exc()}')
    finally:
        hypothesis.core.global_force_seed = None
    return ''


def run(minutes: float, seed: int = 1) -> dict:
    """Run seeds from ``seed`` on for ``minutes`` (at least one); return the figures."""
    from test_engine_interleavings import Interleavings
    started = time.monotonic()
    deadline = started + minutes * 60.0
    seeds, broken = 0, []
    while True:
        took, before = time.monotonic(), Interleavings.sequences
        failure = one(seed + seeds)
        seeds += 1
        verdict = 'ok' if not failure else 'INVARIANT BROKEN'
        print(f'  interleavings: seed {seed + seeds - 1}: '
              f'{Interleavings.sequences - before} sequences {verdict} '
              f'({time.monotonic() - took:.1f} s; {Interleavings.sequences} in all)', flush=True)
        if failure:
            broken.append(seed + seeds - 1)
            print(failure, flush=True)
            print(f'  reproduce: ./dev bench --only interleavings --minutes 0 --seed '
                  f'{seed + seeds - 1}', flush=True)
        if time.monotonic() >= deadline:
            break
    from interleavings import ModelBridge
    excused = sorted(ModelBridge.excused)
    if excused:
        print(f'  interleavings: {len(excused)} heartbeat gap(s) beyond the bound by no more than '
              'the machine delayed a separate idle process then (gap, that delay, ms): '
              + ', '.join(f'{gap * 1000:.0f}/{machine * 1000:.0f}' for _, gap, machine in excused),
              flush=True)
    return {'excused_gaps_ms': [[round(gap * 1000), round(machine * 1000)]
                                for _, gap, machine in excused],
            'sequences': Interleavings.sequences, 'seeds': seeds, 'broken_seeds': broken,
            'steps_each': STEPS, 'minutes': round((time.monotonic() - started) / 60.0, 1),
            'first_seed': seed}


if __name__ == '__main__':
    print(run(float(sys.argv[1]) if len(sys.argv) > 1 else 1.0))
