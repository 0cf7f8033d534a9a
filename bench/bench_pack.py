# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The cost of a pack of two members, per member report, against the engine's own per frame.

The full-load mix of the bench (AMS 5 banks + IVT-S, EVMS3 with 16 BMS12 modules, BMS16 with
its SMA frames; the simulators' frames over ``--seconds`` of simulated time) goes through the
bridge's engine (``engine/core.py``) with a sink that keeps nothing, twice on the same frames:
the five devices alone, and the same with ``pack`` of ``[evms3, bms16]`` (parallel, every limit
configured, so derating and events are computed at each report). CPU per frame
(``time.thread_time``), median of ``--passes`` alternating passes; the pack's share is its
added CPU over the engine's own. The engine without ROS is the smaller part of the bridge's
per-frame cost (publishing is the larger), so this share overstates the pack's share of the
bridge's CPU: issue 36's target (at most 10 %) is measured on the whole bridge by
``bench/run.py --only cpu_pack``.

Run: ``.venv/bin/python bench/bench_pack.py [--json]``. Compare ratios, not absolute figures.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time

from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.core import Engine
from ams_can_bridge.offline.params_file import FileParams
from ams_can_bridge.parameters import NODE_PARAMS
from ams_can_bridge.sim.ams import AmsSimulator
from ams_can_bridge.sim.bms16 import Bms16Simulator
from ams_can_bridge.sim.evms3 import Evms3Simulator
from ams_can_bridge.sim.ivt_s import IvtSSimulator

DEVICES = ['ams', 'ivt_s', 'evms3', 'bms16']
PACK = {'pack.type': 'pack', 'pack.members': ['evms3', 'bms16'],
        'pack.max_charge_current': 40.0, 'pack.max_discharge_current': 80.0,
        'pack.limits.cell_voltage_max': [4.15, 4.2, 4.25],
        'pack.limits.cell_voltage_min': [3.0, 2.8, 2.5],
        'pack.limits.temperature_max': [45.0, 50.0, 55.0],
        'pack.limits.temperature_min': [5.0, 0.0, -10.0]}


class NullSink:
    """Takes every message, keeps nothing."""

    def battery(self, *args: object) -> None:
        """Drop a BatteryState."""

    def figures(self, *args: object) -> None:
        """Drop the Float32 figures."""

    def diagnostics(self, *args: object) -> None:
        """Drop a DiagnosticArray."""

    def clock(self, *args: object) -> None:
        """Drop a clock."""


def frames(seconds: float) -> list[tuple[int, bytes, bool, float]]:
    """Return the full-load mix of ``seconds`` of simulated time, stamped."""
    sims = [AmsSimulator(name='ams', bank_count=5), IvtSSimulator(),
            Evms3Simulator(bms12_modules=16), Bms16Simulator(send_sma=True)]
    out, t = [], 0.0
    while t < seconds:
        for sim in sims:
            out += [(f.arbitration_id, bytes(f.data), f.is_extended_id, t) for f in sim.tick(t)]
        t = round(t + 0.01, 6)
    return out


def engine(with_pack: bool) -> Engine:
    """Return an engine on the devices (and the pack), its clock at the frames' time."""
    names = DEVICES + (['pack'] if with_pack else [])
    values = {'devices': names, 'ams.bank_count': 5, 'evms3.bms12_modules': 16,
              'ivt_s.stale_timeout': 3600.0, 'ams.stale_timeout': 3600.0,
              'evms3.stale_timeout': 3600.0, 'bms16.stale_timeout': 3600.0,
              **{f'{n}.type': n for n in DEVICES}, **(PACK if with_pack else {})}
    params = FileParams(values)
    params.declare_all('', NODE_PARAMS)
    devices = DeviceSet(names, params.declare, clock=lambda: 0.0)
    params.raise_errors()
    status = BusStatus(state=BusState.CONNECTED, reason='', frames_in=0, frames_out=0,
                       frames_dropped_tx=0, error_frames=0, reconnects=0, hardware_id='x')
    return Engine(devices, NullSink(), status_prefix='bench', interface='virtual',
                  bus_status=lambda: status, now=lambda: 0.0, monotonic=lambda: 0.0)


def one_pass(mix: list[tuple[int, bytes, bool, float]], with_pack: bool) -> tuple[float, int]:
    """Return (CPU s per frame, pack updates) of one pass."""
    bench = engine(with_pack)
    on_frame = bench.on_frame
    start = time.thread_time()
    for can_id, data, extended, stamp in mix:
        on_frame(can_id, data, extended, stamp)
    spent = time.thread_time() - start
    pack = bench.devices.get('pack')
    return spent / len(mix), (pack.revision if pack is not None else 0)


def main() -> int:
    """Run the passes and print (or --json) the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=30.0)
    parser.add_argument('--passes', type=int, default=7)
    parser.add_argument('--json', action='store_true')
    args = parser.parse_args()
    mix = frames(args.seconds)
    alone, packed, updates = [], [], 0
    for _ in range(args.passes):
        alone.append(one_pass(mix, False)[0])
        cost, updates = one_pass(mix, True)
        packed.append(cost)
    base, with_pack = statistics.median(alone), statistics.median(packed)
    added = with_pack - base
    result = {'frames': len(mix), 'frames_per_s': len(mix) / args.seconds,
              'pack_updates': updates, 'engine_us_per_frame': base * 1e6,
              'with_pack_us_per_frame': with_pack * 1e6,
              'pack_us_per_update': added * len(mix) / max(updates, 1) * 1e6,
              'added_share': added / base}
    if args.json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f'{key:>24}: {value:.4g}' if isinstance(value, float) else
                  f'{key:>24}: {value}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
