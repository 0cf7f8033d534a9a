# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
An engine with a pack, built from parameters as the bridge builds it, without ROS.

What the pack tests share: ``build`` gives the engine, a sink that keeps every report and
figure by name, and the device set.
"""
from __future__ import annotations

from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.core import Engine
from ams_can_bridge.offline.params_file import FileParams
from ams_can_bridge.parameters import NODE_PARAMS
from helpers import Clock


class PackSink:
    """Every battery report and figure, by name."""

    def __init__(self) -> None:
        self.reports: dict[str, list] = {}
        self.figure_msgs: dict[str, list] = {}
        self.diagnostics_msgs: list = []

    def battery(self, name, frame_id, report, arrays, stamp) -> None:
        self.reports.setdefault(name, []).append((report, stamp))

    def figures(self, name, values, stamp) -> None:
        self.figure_msgs.setdefault(name, []).append((values, stamp))

    def diagnostics(self, statuses, stamp) -> None:
        self.diagnostics_msgs.append(statuses)

    def clock(self, stamp) -> None:
        pass


def build(params: dict, clock: Clock) -> tuple[Engine, PackSink, DeviceSet]:
    """Build the engine of ``params`` on ``clock`` with a PackSink, as the bridge would."""
    file_params = FileParams(params)
    file_params.declare_all('', NODE_PARAMS)
    device_set = DeviceSet(params['devices'], file_params.declare, clock=clock)
    file_params.raise_errors()
    sink = PackSink()
    status = BusStatus(state=BusState.CONNECTED, reason='', frames_in=0, frames_out=0,
                       frames_dropped_tx=0, error_frames=0, reconnects=0, hardware_id='x')
    engine = Engine(device_set, sink, status_prefix='bridge', interface='virtual',
                    bus_status=lambda: status, now=clock, monotonic=clock)
    return engine, sink, device_set
