# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What a wake-up costs: the bridge's own frame work hot (one loop) and as it runs live.

Live, the bridge's receive thread wakes when the serial port has bytes (about every 16 ms
at the car mix's 346 frames/s, ~5 frames a wake-up), does the frames' work and sleeps
again. This bench runs the same work on the same frames (the car mix of ``bench_log2bag``)
in this one process, timed with ``time.thread_time`` (CPU of this thread, kernel
included), two ways: in one loop (hot, as log2bag runs it) and in bursts of ``--burst``
frames with ``--sleep`` s between them (as live). A control sleeps the same number of
times with no work: what the sleep and wake-up themselves cost. Parts:

- ``decode``: each frame's device codec ``decode`` alone (the compiled layouts), no state;
- ``engine``: ``Engine.on_frame`` (decode, state, snapshots) with the sink muted;
- ``whole loop``: log2bag's ``Converter.frame`` (that, the bag, /diagnostics and watch).

Run: ``.venv/bin/python bench/bench_wakeup_cost.py [--frames 6000] [--burst 5]
[--sleep 0.013] [--rounds 2]``; ``--json PATH`` writes the figures.
"""
import argparse
import json
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

PARTS = ('decode', 'engine', 'whole loop')


def car_mix(frames: int) -> list[tuple[int, bytes, bool, float]]:
    """Return the first ``frames`` frames of the bench's car mix as tuples."""
    import can
    from bench_log2bag import simulators
    from ams_can_bridge.sim.recording import write_log
    work = tempfile.mkdtemp(prefix='bench_wakeup_')
    try:
        log = os.path.join(work, 'bus.log')
        write_log(log, simulators(), frames / 266.0 + 2.0)  # the mix: ~266 frames/s
        out = [(m.arbitration_id, bytes(m.data), m.is_extended_id, m.timestamp)
               for m in can.LogReader(log)]
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return out[:frames]


def _call(part: str, bag_dir: str):
    """Return (call(arbitration_id, data, extended, stamp), closer) for a fresh converter."""
    from bench_log2bag import PARAMETERS
    from ams_can_bridge.offline.converter import Converter
    from ams_can_bridge.offline.log2bag import open_bag
    converter = Converter(PARAMETERS, None, 'replay:bench')
    converter.bag = open_bag(bag_dir, 'mcap')
    if part == 'whole loop':
        frame = converter.frame

        def call(arbitration_id: int, data: bytes, extended: bool, stamp: float) -> None:
            frame(arbitration_id, data, extended, stamp, True)
    elif part == 'engine':
        converter.sink.enabled = False
        on_frame = converter.engine.on_frame

        def call(arbitration_id: int, data: bytes, extended: bool, stamp: float) -> None:
            converter.now = stamp
            on_frame(arbitration_id, data, extended, stamp)
    else:
        targets = converter.devices.handle_targets

        def call(arbitration_id: int, data: bytes, extended: bool, stamp: float) -> None:
            for device in targets(arbitration_id, extended):
                device.codec.decode(arbitration_id, data)
    return call, converter.bag.close


def run(part: str, frames: list, burst: int, sleep: float) -> float:
    """Return CPU us per frame of ``part`` over the frames, ``burst`` at a time."""
    work = tempfile.mkdtemp(prefix='bench_wakeup_bag_')
    try:
        call, close = _call(part, os.path.join(work, 'bag'))
        start = time.thread_time()
        for i in range(0, len(frames), burst):
            for arbitration_id, data, extended, stamp in frames[i:i + burst]:
                call(arbitration_id, data, extended, stamp)
            if sleep:
                time.sleep(sleep)
        cost = time.thread_time() - start
        close()
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return cost / len(frames) * 1e6


def sleeps_only(frames: int, burst: int, sleep: float) -> float:
    """Return CPU us per frame of the sleeps alone (the control)."""
    start = time.thread_time()
    for _ in range(0, frames, burst):
        time.sleep(sleep)
    return (time.thread_time() - start) / frames * 1e6


def main() -> None:
    """Measure every part hot and in bursts; print the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--frames', type=int, default=6000)
    parser.add_argument('--burst', type=int, default=5, help='frames a wake-up (live: ~5)')
    parser.add_argument('--sleep', type=float, default=0.013, help='s between bursts')
    parser.add_argument('--rounds', type=int, default=2)
    parser.add_argument('--json', default='')
    args = parser.parse_args()
    frames = car_mix(args.frames)
    hot: dict[str, list[float]] = {p: [] for p in PARTS}
    cold: dict[str, list[float]] = {p: [] for p in PARTS}
    control: list[float] = []
    for _ in range(args.rounds):
        for part in PARTS:
            hot[part].append(run(part, frames, len(frames), 0.0))
            cold[part].append(run(part, frames, args.burst, args.sleep))
        control.append(sleeps_only(len(frames), args.burst, args.sleep))
    sleep_cost = min(control)
    print(f'{len(frames):,} frames of the car mix; CPU us a frame, min of {args.rounds} rounds; '
          f'bursts of {args.burst} frames, {args.sleep * 1e3:g} ms apart; the sleeps alone '
          f'{sleep_cost:.2f} us a frame ({sleep_cost * args.burst:.0f} us a wake-up)')
    print(f'{"part":<12}{"hot":>8}{"bursts":>9}{"- sleeps":>10}{"cold/hot":>10}')
    rows = []
    for part in PARTS:
        h, c = min(hot[part]), min(cold[part])
        work = c - sleep_cost
        rows.append({'part': part, 'hot_us': h, 'bursts_us': c, 'work_in_bursts_us': work,
                     'cold_over_hot': work / h})
        print(f'{part:<12}{h:>8.2f}{c:>9.2f}{work:>10.2f}{work / h:>9.2f}x')
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump({'frames': len(frames), 'burst': args.burst, 'sleep_s': args.sleep,
                       'sleeps_us_per_frame': sleep_cost, 'parts': rows}, stream, indent=1)


if __name__ == '__main__':
    main()
