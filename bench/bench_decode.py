# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Decode benchmark: frames per second through each protocol codec vs bare cantools.

The frame mix is what the simulators send over 60 simulated seconds (realistic ratios of
status, cell and temperature frames). For each protocol the same frames go through
``codec.decode`` (our typed readings) and through cantools ``decode_message`` on the
protocol's DBC, in the same run; the ratio is what counts (target: codec <= 2x cantools).
Run: ``./dev bench`` or ``.venv/bin/python bench/bench_decode.py [--seconds 60]``.
"""
import argparse
import time

from ams_can_bridge import registry
from ams_can_bridge.protocols.ams import AmsCodec
from ams_can_bridge.protocols.bms16 import Bms16Codec
from ams_can_bridge.protocols.common import load_dbc
from ams_can_bridge.protocols.evms3 import Evms3Codec
from ams_can_bridge.protocols.ivt_s import IvtSCodec
from ams_can_bridge.protocols.sma import SmaCodec

CODECS = {
    'ams': AmsCodec(), 'ivt_s': IvtSCodec(), 'evms3': Evms3Codec(),
    'bms16': Bms16Codec(), 'sma': SmaCodec(),
}
SIM_OPTIONS = {'ams': {'bank_count': 5}, 'evms3': {'bms12_modules': 8}}


def frame_mix(seconds: float) -> dict[str, list[tuple[int, bytes]]]:
    """Run every simulator for `seconds` of simulated time; group its frames by protocol."""
    mix: dict[str, list[tuple[int, bytes, bool]]] = {name: [] for name in CODECS}
    for device_type, path in registry.SIMULATORS.items():
        if device_type not in CODECS:  # dbc: bench/bench_dbc.py
            continue
        sim = registry.load(path)(**SIM_OPTIONS.get(device_type, {}))
        # A BMS16 also sends SMA frames; IDs can repeat across protocols (AMS 0x351 is
        # SMA 0x351), so a frame goes to its own device's codec first.
        owners = [device_type] + (['sma'] if device_type == 'bms16' else [])
        t = 0.0
        while t < seconds:
            for frame in sim.tick(t):
                for name in owners:
                    if frame.arbitration_id in CODECS[name].arbitration_ids:
                        mix[name].append((frame.arbitration_id, bytes(frame.data),
                                          frame.is_extended_id))
                        break
            t += 0.005
    return mix


def rate(fn, frames: list[tuple[int, bytes, bool]], repeat: int) -> float:
    """Return frames per second of fn(id, data) over the frames, best of `repeat` passes."""
    best = float('inf')
    for _ in range(repeat):
        start = time.perf_counter()
        for arbitration_id, data, _extended in frames:
            fn(arbitration_id, data)
        best = min(best, time.perf_counter() - start)
    return len(frames) / best


def main() -> None:
    """Measure and print one row per protocol."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=60.0, help='simulated time per device')
    parser.add_argument('--repeat', type=int, default=5, help='passes; the best one counts')
    args = parser.parse_args()
    mix = frame_mix(args.seconds)
    print(f'{"protocol":8} {"frames":>7} {"codec f/s":>12} {"cantools f/s":>13} {"ratio":>6}')
    for name, frames in mix.items():
        if not frames:
            continue
        db = load_dbc(name)
        codec = CODECS[name]
        ours = rate(lambda i, data: codec.decode(i, data), frames, args.repeat)
        # cantools keys 29-bit frames with the extended flag; look messages up once, as a
        # bare cantools user with a dispatch table would.
        by_id = {(m.frame_id, m.is_extended_frame): m for m in db.messages}
        table = {i: by_id[(i, ext)].decode for i, _, ext in frames}
        bare = rate(lambda i, data: table[i](data), frames, args.repeat)
        print(f'{name:8} {len(frames):7d} {ours:12,.0f} {bare:13,.0f} {bare / ours:5.2f}x')
    print('ratio = codec time / cantools time for the same frames (target <= 2.00x)')


if __name__ == '__main__':
    main()
