# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Measure how closely a replay keeps its log's timing at several rates (figures, not a test).

A 2 s log of 21 frames (100 ms apart) plays through CanIo at each rate; printed per rate: the
span the frames took against the scaled log span, and the worst lateness of one frame. The
test suite only checks which rate played
(test_can_io_replay_record.py::test_replay_rate_scales_time).

    .venv/bin/python bench/bench_replay_rate.py [--rates 1 2 4 10]
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

import can

from ams_can_bridge.bus_state import BusState
from ams_can_bridge.can_io import BusConfig, CanIo

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')


def write_log(path: str, frames: int = 21, gap: float = 0.1) -> None:
    writer = can.Logger(path)
    for k in range(frames):
        writer.on_message_received(can.Message(timestamp=1_700_000_000.0 + k * gap,
                                               arbitration_id=0x300, data=bytes([k]),
                                               is_extended_id=False, channel='can0'))
    writer.stop()


def play(path: str, rate: float) -> list[float]:
    arrivals: list[float] = []
    io = CanIo(BusConfig(interface='replay', channel=path, replay_rate=rate),
               lambda *_: arrivals.append(time.monotonic()))
    io.start()
    try:
        while io.status().state != BusState.REPLAY_FINISHED:
            time.sleep(0.01)
    finally:
        io.stop()
    return arrivals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--rates', type=float, nargs='+', default=[1.0, 2.0, 4.0, 10.0])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, 'bench.log')
        write_log(path)
        print('rate   scaled span s   played span s   ratio   worst late ms')
        for rate in args.rates:
            arrivals = play(path, rate)
            due = [k * 0.1 / rate for k in range(len(arrivals))]
            late = max((a - arrivals[0]) - d for a, d in zip(arrivals, due))
            span = arrivals[-1] - arrivals[0]
            print(f'{rate:4g}   {due[-1]:13.3f}   {span:13.3f}   {span / due[-1]:5.3f}   '
                  f'{late * 1000:13.1f}')


if __name__ == '__main__':
    main()
