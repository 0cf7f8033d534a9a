# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The live bridge's periodic thread (``TimerThread``): its CPU per task, idle and at full load.

    .venv/bin/python bench/periodic_thread.py [TREE] [--seconds 20] [--profile PREFIX]
        [--wrap module.Class.method,...]

Starts the bridge of TREE (default: this checkout) over slcan on a pty pair, 20 s with a
silent bus, then 20 s with the simulator's full load (5 devices, 346 frames/s), and prints
for each: the thread's CPU from /proc (schedstat, ns: the kernel's sleep/wake-up included),
its CPU after each wake-up, the wake-ups a second, and each task's (and each ``--wrap``'ed
method's) CPU a second and a call, timed with ``time.thread_time_ns`` on that thread.
``--profile PREFIX`` adds a cProfile of the thread per phase (PREFIXidle.txt, PREFIXload.txt;
it slows what it measures). bench/README.md, "Fifth pass", has the figures it gave.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from typing import Any

CHILD = '--child'


def child() -> None:
    """Run the bridge with its TimerThread instrumented; answer snapshot requests by file."""
    import cProfile
    import importlib
    import pstats
    import threading
    run = os.environ['PERIODIC_BENCH_RUN']
    from ams_can_bridge.engine import timer
    stats: dict[str, Any] = {'tasks': {}, 'wakeups': 0, 'busy_ns': 0, 'tid': None}
    prof: dict[str, Any] = {'want': False, 'profile': None, 'out': ''}

    def count(name: str, start: int) -> None:
        rec = stats['tasks'].setdefault(name, [0, 0])
        rec[0] += 1
        rec[1] += time.thread_time_ns() - start

    class Wake:
        """The thread's wake lock, counting wake-ups and the CPU after each."""

        def __init__(self, lock: Any) -> None:
            self.lock, self.since = lock, None

        def acquire(self, timeout: float = -1) -> bool:
            if self.since is not None:
                stats['busy_ns'] += time.thread_time_ns() - self.since
            if prof['want'] and prof['profile'] is None:
                prof['profile'] = cProfile.Profile()
                prof['profile'].enable()
            elif not prof['want'] and prof['profile'] is not None:
                prof['profile'].disable()
                with open(prof['out'], 'w', encoding='utf-8') as stream:
                    for order in ('tottime', 'cumtime'):
                        pstats.Stats(prof['profile'], stream=stream).sort_stats(
                            order).print_stats(50)
                prof['profile'] = None
            got = self.lock.acquire(timeout=timeout)
            stats['wakeups'] += 1
            self.since = time.thread_time_ns()
            return bool(got)

        def release(self) -> None:
            self.lock.release()

    run_loop, call = timer.TimerThread._run, timer.TimerThread._call

    def _run(self: Any, wake: Any) -> None:
        stats['tid'] = threading.get_native_id()
        run_loop(self, Wake(wake))

    def _call(self: Any, task: list, now: float) -> None:
        start = time.thread_time_ns()
        try:
            call(self, task, now)
        finally:
            count(getattr(task[2], '__name__', str(task[2])), start)
    timer.TimerThread._run, timer.TimerThread._call = _run, _call  # type: ignore[method-assign]
    for dotted in filter(None, os.environ.get('PERIODIC_BENCH_WRAP', '').split(',')):
        module, cls, name = dotted.rsplit('.', 2)
        klass = getattr(importlib.import_module(module), cls)

        def wrapped(*args: Any, _f: Any = getattr(klass, name), _n: str = f'{cls}.{name}',
                    **kwargs: Any) -> Any:
            start = time.thread_time_ns()
            try:
                return _f(*args, **kwargs)
            finally:
                if threading.get_native_id() == stats['tid']:
                    count(_n, start)
        setattr(klass, name, wrapped)

    def answer() -> None:
        request = os.path.join(run, 'request')
        while True:
            time.sleep(0.2)
            if not os.path.exists(request):
                continue
            with open(request, encoding='utf-8') as stream:
                what = stream.read().split()
            if what[0] == 'profile':
                prof['out'], prof['want'] = what[1], True
            elif what[0] == 'unprofile':
                prof['want'] = False
            try:
                with open(f'/proc/self/task/{stats["tid"]}/schedstat', encoding='ascii') as s:
                    sched = int(s.read().split()[0])
            except (OSError, ValueError):
                sched = 0
            snap = {'tasks': {k: list(v) for k, v in stats['tasks'].items()},
                    'wakeups': stats['wakeups'], 'busy_ns': stats['busy_ns'],
                    'sched_ns': sched, 'mono': time.monotonic()}
            with open(os.path.join(run, 'answer.tmp'), 'w', encoding='utf-8') as stream:
                json.dump(snap, stream)
            os.remove(request)
            os.rename(os.path.join(run, 'answer.tmp'), os.path.join(run, 'answer'))
    threading.Thread(target=answer, daemon=True, name='periodic-bench').start()
    from ams_can_bridge.ros import bridge_main
    sys.argv = ['bridge'] + sys.argv[2:]
    bridge_main.main()


def main() -> None:
    """Measure one tree's periodic thread, idle then at full load."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('tree', nargs='?', default=os.path.dirname(os.path.dirname(
        os.path.abspath(__file__))))
    parser.add_argument('--seconds', type=float, default=20.0)
    parser.add_argument('--profile', default='', metavar='PREFIX')
    parser.add_argument('--wrap', default='', help='module.Class.method,... timed too')
    args = parser.parse_args()
    tree = os.path.abspath(args.tree)
    sys.path[:0] = [os.path.join(tree, 'bench'), tree]
    os.environ['PYTHONPATH'] = tree  # the bridge child imports this tree's package
    os.environ['PERIODIC_BENCH_WRAP'] = args.wrap
    os.chdir(tree)
    from harness import (PYTHON, SLCAN_OPEN, bridge_args, process, pty_pair, simulator_args,
                         write_params)
    run = tempfile.mkdtemp(prefix='periodic-bench-')
    os.environ['PERIODIC_BENCH_RUN'] = run

    def ask(what: str) -> dict[str, Any]:
        answer = os.path.join(run, 'answer')
        if os.path.exists(answer):
            os.remove(answer)
        with open(os.path.join(run, 'request.tmp'), 'w', encoding='utf-8') as stream:
            stream.write(what)
        os.rename(os.path.join(run, 'request.tmp'), os.path.join(run, 'request'))
        for _ in range(200):
            time.sleep(0.05)
            if os.path.exists(answer):
                with open(answer, encoding='utf-8') as stream:
                    result: dict[str, Any] = json.load(stream)
                    return result
        raise RuntimeError('the bridge did not answer (did it start?)')

    def phase(label: str) -> None:
        first = ask(f'profile {args.profile}{label}.txt' if args.profile else 'snapshot')
        time.sleep(args.seconds)
        last = ask('unprofile' if args.profile else 'snapshot')
        wall = last['mono'] - first['mono']
        print(f'{label}: thread {(last["sched_ns"] - first["sched_ns"]) / 1e6 / wall:.3f} '
              f'ms/s, after wake-ups {(last["busy_ns"] - first["busy_ns"]) / 1e6 / wall:.3f} '
              f'ms/s, {(last["wakeups"] - first["wakeups"]) / wall:.2f} wake-ups/s')
        for name, (calls, ns) in last['tasks'].items():
            calls0, ns0 = first['tasks'].get(name, (0, 0))
            if calls > calls0:
                print(f'   {name:28s} {(ns - ns0) / 1e6 / wall:7.3f} ms/s '
                      f'{(calls - calls0) / wall:6.2f} calls/s '
                      f'{(ns - ns0) / 1e3 / (calls - calls0):8.1f} us/call', flush=True)

    with tempfile.TemporaryDirectory() as work, pty_pair() as (a, b):
        params = write_params(os.path.join(work, 'p.yaml'), 'slcan', b, SLCAN_OPEN)
        command = [PYTHON, os.path.abspath(__file__), CHILD] + bridge_args(params)[3:]
        with process(command, settle=5.0):
            phase('idle')
            with process(simulator_args(a), settle=4.0):
                phase('load')


if __name__ == '__main__':
    if len(sys.argv) > 1 and sys.argv[1] == CHILD:
        child()
    else:
        main()
