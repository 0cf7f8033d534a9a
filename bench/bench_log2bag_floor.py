# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's floor: the least a conversion that decodes every frame must do, beside the read.

Issue 39 point 1 asks log2bag for >= 0.5x python-can's read of the same file. This bench
asks how close a conversion can come at all, in one run per format, each part timed over
the whole file (``time.perf_counter``), the parts in turns, min of ``--rounds``:

- ``python-can read``: ``can.LogReader`` over the file: the reference;
- ``own read``: log2bag's reader (``LogFrames.frames``) alone;
- ``+ decode``: that, and each frame's device codec ``decode`` (the compiled layouts, the
  protocol's range checks), no device state;
- ``+ messages``: that, and serialising and writing into a bag every message the real
  conversion writes, from the reports, arrays and statuses it made, recorded beforehand:
  the bytes cost, not the state, the snapshots or the diagnostic values behind them;
- ``log2bag``: the real conversion (``convert``).

``+ messages`` is a floor for any design with this reader, these codecs and this bag
writer: the work it leaves out (counters, freshness, reports, diagnostic values) is what a
redesign of the devices' state would make cheaper, never free. Its ratio is the best point
1 can reach without a faster reader, decoder or serializer; the rate left between it and
0.5x is the budget of that work, printed per frame.
Run: ``.venv/bin/python bench/bench_log2bag_floor.py [--seconds 300] [--rounds 3]``.
"""
import argparse
import copy
import gc
import json
import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

PARTS = ('python-can read', 'own read', '+ decode', '+ messages', 'log2bag')


class _Recorder:
    """A bag sink that keeps what the engine emits, with the frame it came with."""

    def __init__(self) -> None:
        self.enabled = True
        self.frame = 0
        self.events: list[tuple[int, str, tuple]] = []

    def battery(self, name, frame_id, report, arrays, stamp) -> None:
        arrays = {suffix: (rows, cols, list(data)) for suffix, (rows, cols, data)
                  in arrays.items()}  # a device may reuse its lists
        self.events.append((self.frame, 'battery', (name, frame_id, report, arrays, stamp)))

    def figures(self, name, values, stamp) -> None:
        self.events.append((self.frame, 'figures', (name, dict(values), stamp)))

    def diagnostics(self, statuses, stamp) -> None:
        self.events.append((self.frame, 'diagnostics', (copy.deepcopy(statuses), stamp)))

    def clock(self, stamp) -> None:
        pass


def record(log: str) -> tuple[list, str]:
    """Convert ``log`` with a recording sink; return its events and its hardware id."""
    from bench_log2bag import PARAMETERS
    from ams_can_bridge.offline.converter import Converter
    from ams_can_bridge.offline.log_frames import LogFrames
    converter = Converter(PARAMETERS, None, f'replay:{log}')
    recorder = _Recorder()
    converter.engine.sink = recorder
    frames = LogFrames(log)
    last = 0.0
    for index, (stamp, arbitration_id, data, extended, error, remote) in enumerate(
            frames.frames()):
        recorder.frame = index
        if not (error or remote):
            converter.frame(arbitration_id, data, extended, stamp, True)
            last = stamp
    frames.close()
    recorder.frame += 1
    converter.finish(last)
    return recorder.events, converter.hardware_id


def _decoders(devices) -> dict:
    """Return (id, extended) -> the decode calls of the devices the device set routes it to."""
    return {(can_id, extended): [device.codec.decode for device in targets]
            for extended, table in ((False, devices.std), (True, devices.ext))
            for can_id, targets in table.items()}


def part(name: str, log: str, events: list, hardware_id: str, work: str) -> tuple[float, int]:
    """Run one part over the whole file; return (seconds, frames)."""
    import can
    from bench_log2bag import PARAMETERS
    from ams_can_bridge.offline.converter import BagSink, Converter
    from ams_can_bridge.offline.log2bag import convert, open_bag
    from ams_can_bridge.offline.log_frames import LogFrames
    from ams_can_bridge.errors import ProtocolError
    out = tempfile.mkdtemp(prefix='floor_', dir=work)
    os.rmdir(out)
    if name == 'python-can read':
        start = time.perf_counter()
        count = sum(1 for _ in can.LogReader(log))
        return time.perf_counter() - start, count
    if name == 'log2bag':
        start = time.perf_counter()
        with open(os.devnull, 'w', encoding='utf-8') as quiet:  # no progress lines
            summary = convert(log, out, PARAMETERS, progress_stream=quiet)
        return time.perf_counter() - start, summary.frames_read
    decoders = _decoders(Converter(PARAMETERS, None, 'floor').devices)
    bag = open_bag(out, 'mcap') if name == '+ messages' else None
    sink = BagSink(hardware_id)  # writes each recorded message as the conversion's sink does
    sink.bag, sink.enabled = bag, True
    pending = iter(events if bag is not None else ())
    upcoming = next(pending, None)
    start = time.perf_counter()
    frames = LogFrames(log)
    count = 0
    for stamp, arbitration_id, data, extended, error, remote in frames.frames():
        if name != 'own read':
            for decode in decoders.get((arbitration_id, extended), ()):
                try:
                    decode(arbitration_id, data)
                except ProtocolError:
                    pass
        while upcoming is not None and upcoming[0] <= count:
            getattr(sink, upcoming[1])(*upcoming[2])
            upcoming = next(pending, None)
        count += 1
    frames.close()
    while upcoming is not None:  # the last /diagnostics, after the last frame
        getattr(sink, upcoming[1])(*upcoming[2])
        upcoming = next(pending, None)
    if bag is not None:
        bag.close()
    return time.perf_counter() - start, count


def measure(seconds: float, formats: list[str], rounds: int) -> list[dict]:
    """Return one row per format: seconds of each part (min of rounds), frames, ratios."""
    from bench_log2bag import RATIO_TARGET, simulators
    from ams_can_bridge.sim.recording import write_log
    work = tempfile.mkdtemp(prefix='bench_floor_')
    rows = []
    try:
        for fmt in formats:
            log = os.path.join(work, f'bus.{fmt}')
            frames = write_log(log, simulators(), seconds)
            events, hardware_id = record(log)
            # the recorded messages are many objects that live to the end: out of the
            # collector's way, or every part pays for walking them
            gc.collect()
            gc.freeze()
            best = dict.fromkeys(PARTS, float('inf'))
            for k in range(rounds):
                order = PARTS if k % 2 == 0 else tuple(reversed(PARTS))
                for name in order:
                    took, count = part(name, log, events, hardware_id, work)
                    assert count == frames, (name, count, frames)
                    best[name] = min(best[name], took)
            read = best['python-can read']
            rows.append({
                'format': fmt, 'frames': frames, 'messages': len(events), 'seconds': best,
                'us_per_frame': {n: s / frames * 1e6 for n, s in best.items()},
                'ratio': {n: read / s for n, s in best.items()},
                # what a frame may cost beyond + messages for 0.5x: the state's budget
                'budget_us': (read / RATIO_TARGET - best['+ messages']) / frames * 1e6,
                'state_now_us': (best['log2bag'] - best['+ messages']) / frames * 1e6})
    finally:
        gc.unfreeze()
        shutil.rmtree(work, ignore_errors=True)
    return rows


def main() -> None:
    """Measure each format; print the table (and --json)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--seconds', type=float, default=300.0,
                        help='simulated seconds of the car mix (about 266 frames/s)')
    parser.add_argument('--formats', default='log,blf')
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--json', default='')
    args = parser.parse_args()
    rows = measure(args.seconds, args.formats.split(','), args.rounds)
    for row in rows:
        print(f"{row['format']}: {row['frames']:,} frames ({args.seconds:g} s car mix), "
              f"{row['messages']:,} messages written; min of {args.rounds} rounds")
        print(f'  {"part":<17}{"us/frame":>9}{"x read":>8}')
        for name in PARTS:
            print(f'  {name:<17}{row["us_per_frame"][name]:>9.2f}{row["ratio"][name]:>8.2f}')
        print(f"  state, snapshots, values: {row['state_now_us']:.2f} us/frame now; "
              f"0.5x leaves them {row['budget_us']:.2f}")
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump({'log2bag_floor': rows}, stream, indent=2)


if __name__ == '__main__':
    main()
