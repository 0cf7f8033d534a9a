# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge's own cost per frame: everything but python-can's recv, at the realistic mix.

The simulators' frames (AMS 5 banks, EVMS3 16 BMS12, BMS16 + SMA, IVT-S; ~346 frames/s) are
captured for ``--seconds`` of simulated time, then given to ``Engine.on_frame``, what the
bus thread calls (decode -> device state -> BatteryState/arrays -> rclpy publish), of a
bridge on python-can ``virtual`` that receives nothing else:

- **tight loop**: every captured frame back to back, ``--passes`` times; CPU per frame
  (``time.thread_time``), the best and the median pass. Warm caches: a lower bound.
- **paced**: ``--paced`` s of the same frames at their real rate (one batch per 10 ms tick)
  from a thread of their own, while the bridge's periodic thread runs as in the field
  (diagnostics 1 Hz, watch 5 Hz, stale messages 1 Hz): CPU per frame of the feeding (the
  sleeps between ticks left out), and the periodic thread's CPU in us per second, whole
  and split by task (the rest is its wake-ups). After 10 ms asleep the caches are cold: on
  the 2-core VM this was written on, a publish costs ~80 us instead of ~12 us in the tight
  loop, so these figures are several times the tight ones and closer to the field.
- ``--profile``: a cProfile of one tight pass, the top ``--top`` functions by own time.

Run: ``.venv/bin/python bench/bench_own_path.py [--profile]``. Figures move with the load of
the machine: compare two versions alternately in the same minute (A/B), not across days.
"""
from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import statistics
import threading
import time

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

import rclpy  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from ams_can_bridge import registry  # noqa: E402
from ams_can_bridge.ros.bridge_node import BridgeNode  # noqa: E402

DEVICES = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma')
SIM_OPTIONS = {'ams': {'bank_count': 5}, 'evms3': {'bms12_modules': 16},
               'bms16': {'send_sma': True}}
TICK = 0.01  # s of simulated time per batch


def capture(seconds: float) -> list[list[tuple[int, bytes, bool]]]:
    """Return the simulators' frames, one list per 10 ms tick (sma comes from the bms16)."""
    sims = [registry.load(registry.SIMULATORS[n])(name=n, **SIM_OPTIONS.get(n, {}))
            for n in DEVICES if n != 'sma']
    ticks = []
    t = 1000.0
    for _ in range(int(round(seconds / TICK))):
        t += TICK
        ticks.append([(f.arbitration_id, bytes(f.data), f.is_extended_id)
                      for s in sims for f in s.tick(t)])
    return ticks


def make_node() -> BridgeNode:
    """Return a bridge with the five devices on a virtual bus nobody writes to."""
    return BridgeNode(parameter_overrides=[
        Parameter('can.interface', value='virtual'),
        Parameter('can.channel', value=f'bench_own_{os.getpid()}'),
        Parameter('devices', value=list(DEVICES)), Parameter('ams.bank_count', value=5),
        Parameter('evms3.bms12_modules', value=16)])


def tight(node: BridgeNode, frames: list, passes: int) -> list[float]:
    """Return the CPU us per frame of each back-to-back pass."""
    on_frame = node.engine.on_frame  # what the bus thread calls
    out = []
    for _ in range(passes):
        c0 = time.thread_time()
        for a, d, e in frames:
            on_frame(a, d, e, time.time())
        out.append((time.thread_time() - c0) / len(frames) * 1e6)
    return out


def paced(node: BridgeNode, ticks: list, seconds: float) -> dict:
    """Feed the ticks at their real rate for `seconds`; return the feeder and periodic CPU."""
    spent: dict[str, float] = {}
    calls: dict[str, int] = {}

    def timed(name, callback):
        def run():
            c0 = time.thread_time()
            try:
                callback()
            finally:
                spent[name] = spent.get(name, 0.0) + time.thread_time() - c0
                calls[name] = calls.get(name, 0) + 1
        return run

    for task in node.periodic._tasks:
        task[2] = timed(getattr(task[2], '__name__', str(task[2])), task[2])
    clock = time.pthread_getcpuclockid(node.periodic._thread.ident)
    result = {}

    def feed():
        on_frame = node.engine.on_frame  # what the bus thread calls
        n = 0
        spent = 0.0  # CPU of the feeding itself, the sleeps between ticks left out
        start = time.monotonic()
        for i in range(int(round(seconds / TICK))):
            c0 = time.thread_time()
            for a, d, e in ticks[i % len(ticks)]:
                on_frame(a, d, e, time.time())
                n += 1
            spent += time.thread_time() - c0
            delay = start + (i + 1) * TICK - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        result['feed_us'] = spent / n * 1e6
        result['frames'] = n

    p0 = time.clock_gettime(clock)
    w0 = time.monotonic()
    feeder = threading.Thread(target=feed)
    feeder.start()
    feeder.join()
    wall = time.monotonic() - w0
    result['periodic_us_s'] = (time.clock_gettime(clock) - p0) / wall * 1e6
    result['tasks'] = {name: (spent[name] / wall * 1e6, calls[name]) for name in spent}
    result['rate'] = result['frames'] / wall
    return result


def main() -> None:
    """Measure and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=20.0, help='simulated s captured')
    parser.add_argument('--passes', type=int, default=5, help='tight-loop passes')
    parser.add_argument('--paced', type=float, default=10.0,
                        help='s of real-rate feeding with the periodic thread (0: skip)')
    parser.add_argument('--profile', action='store_true', help='cProfile one tight pass')
    parser.add_argument('--top', type=int, default=30, help='profile rows')
    args = parser.parse_args()

    ticks = capture(args.seconds)
    frames = [f for tick in ticks for f in tick]
    print(f'{len(frames)} frames, {len(frames) / args.seconds:.0f} frames/s simulated')
    rclpy.init()
    node = make_node()
    try:
        tight(node, frames, 1)  # warm up: every device heard, every cache filled
        runs = tight(node, frames, args.passes)
        print(f'own path, tight loop:  {min(runs):6.2f} us/frame best, '
              f'{statistics.median(runs):6.2f} median of {len(runs)} passes')
        if args.paced > 0:
            r = paced(node, ticks, args.paced)
            print(f'own path, paced:       {r["feed_us"]:6.2f} us/frame '
                  f'({r["frames"]} frames at {r["rate"]:.0f}/s)')
            print(f'periodic thread:       {r["periodic_us_s"]:6.0f} us/s '
                  f'({r["periodic_us_s"] / 1e4:.3f} % of a core)')
            for name, (us, n) in sorted(r['tasks'].items(), key=lambda kv: -kv[1][0]):
                print(f'  {name:22s} {us:6.0f} us/s ({n} calls, {us * args.paced / n:.0f} '
                      'us/call)')
        if args.profile:
            profile = cProfile.Profile()
            on_frame = node.engine.on_frame  # what the bus thread calls
            profile.enable()
            for a, d, e in frames:
                on_frame(a, d, e, time.time())
            profile.disable()
            pstats.Stats(profile).sort_stats('tottime').print_stats(args.top)
    finally:
        node.destroy_node()
        rclpy.shutdown()


if __name__ == '__main__':
    main()
