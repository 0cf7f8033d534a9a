# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's engine on the log's time: the bridge's own engine fed frame by frame, a bag sink.

``Converter`` builds the devices from the same parameters file as the live bridge and runs
the engine (``engine/core.py``) with its clocks set to the log time: each frame at its log
stamp, the periodic work (a silent device's ``present: false``, ``/diagnostics``) at the log
moment it was due. ``BagSink`` writes what the engine emits, muted before ``--start``.
Reading the log, the bag's file and the command line are ``offline/log2bag.py``'s.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.base import BatteryReport
from ams_can_bridge.engine.core import Arrays, Engine, Schedule, STALE_PUBLISH_PERIOD, Statuses
from ams_can_bridge.offline.params_file import FileParams
from ams_can_bridge.parameters import BUS_PARAMS, NODE_PARAMS

if TYPE_CHECKING:  # rosbags is imported only when a bag is written
    from ams_can_bridge.offline.bag import BagOut

NODE_NAME = 'ams_can_bridge'  # the bridge's default node name: its entry in params files


class BagSink:
    """The engine's bag sink: every message written at its stamp (muted before --start)."""

    def __init__(self, hardware_id: str) -> None:
        """Write nothing until ``bag`` is set and ``enabled`` is true."""
        self.bag: BagOut | None = None
        self.hardware_id = hardware_id
        self.enabled = False

    def battery(self, name: str, frame_id: str, report: BatteryReport, arrays: Arrays,
                stamp: float) -> None:
        """Write a BatteryState and its arrays, header stamp and bag time = stamp."""
        if self.enabled and self.bag is not None:
            self.bag.battery_state(f'/{name}/battery_state', report, frame_id, stamp)
            for suffix, (rows, cols, data) in arrays.items():
                self.bag.multi_array(f'/{name}/{suffix}', rows, cols, data, stamp)

    def figures(self, name: str, values: dict[str, float], stamp: float) -> None:
        """Write a pack's std_msgs/Float32 figures at bag time stamp."""
        if self.enabled and self.bag is not None:
            for suffix, value in values.items():
                self.bag.float32(f'/{name}/{suffix}', value, stamp)

    def diagnostics(self, statuses: Statuses, stamp: float) -> None:
        """Write one /diagnostics at stamp."""
        if self.enabled and self.bag is not None:
            self.bag.diagnostics(statuses, self.hardware_id, stamp)

    def clock(self, stamp: float) -> None:
        """Write nothing: a bag's time is its messages' own."""


class Converter:
    """Feed frames to the engine on the log's time; the bag sink writes what it emits."""

    def __init__(self, parameters: dict, bag: BagOut | None, hardware_id: str,
                 node_name: str = NODE_NAME) -> None:
        """
        Build the devices from flat parameter values; raise ConfigError naming bad ones.

        node_name names the statuses as the live bridge does: with its namespace, without
        the leading slash ('car2/ams_can_bridge: ams').
        """
        status_prefix = node_name.strip('/') or NODE_NAME
        params = FileParams(parameters)
        params.declare_all('can.', BUS_PARAMS)  # checked like the bridge's, not used
        node = params.declare_all('', NODE_PARAMS)
        self.now = math.nan
        self.devices = DeviceSet(node['devices'], params.declare, clock=lambda: self.now)
        params.raise_errors()
        self.diagnostics_period = node['diagnostics_period']
        self.hardware_id = hardware_id
        self.sink = BagSink(hardware_id)
        self.bag = bag
        self.frames_in = 0
        self.error_frames = 0
        self.state = BusState.CONNECTED
        # the engine's clocks are the log's time: its periodic work runs at log moments
        self.engine = Engine(self.devices, self.sink, status_prefix=status_prefix,
                             interface='replay', bus_status=self._bus_status,
                             now=lambda: self.now, monotonic=lambda: self.now)
        self.last_frame = math.nan  # the log time of the last frame (any ID)
        tasks = [(period, self._repeat_stale if call == self.engine.publish_stale else call)
                 for period, call in self.engine.schedule(self.diagnostics_period)]
        self.schedule = Schedule(tasks, self._set_now, self.engine.quiet_horizon())

    @property
    def bag(self) -> BagOut | None:
        """Return the bag written to (None: nothing is written)."""
        return self.sink.bag

    @bag.setter
    def bag(self, bag: BagOut | None) -> None:
        self.sink.bag = bag

    def _set_now(self, now: float) -> None:
        self.now = now

    def _repeat_stale(self) -> None:
        """
        Repeat the present: false of the silent devices (every second) while the log goes on.

        In a gap of the log (no frame for a stale period) nothing is repeated: each device's
        going stale is still written once (the watch), the rest of the gap adds nothing.
        """
        if self.now - self.last_frame <= STALE_PUBLISH_PERIOD:
            self.engine.publish_stale()

    def _bus_status(self) -> BusStatus:
        return BusStatus(state=self.state, reason='', frames_in=self.frames_in, frames_out=0,
                         frames_dropped_tx=0, error_frames=self.error_frames, reconnects=0,
                         hardware_id=self.hardware_id)

    def frame(self, arbitration_id: int, data: bytes, is_extended_id: bool, stamp: float,
              write: bool) -> None:
        """Apply one frame at log time stamp; write its messages when write is true."""
        if write:  # the periodic work due before this frame, each at its own moment
            schedule = self.schedule
            if not schedule.started:  # the first written frame starts the grid
                schedule.start(stamp)
            elif schedule.last <= stamp < schedule.due:  # most frames: nothing due, no call
                schedule.last = stamp
            else:
                schedule.run_until(stamp)
        self.now = self.last_frame = stamp
        self.frames_in += 1
        self.sink.enabled = write
        self.engine.on_frame(arbitration_id, data, is_extended_id, stamp)

    def finish(self, stamp: float) -> None:
        """Write the last /diagnostics at the end of the log: the replay finished."""
        self.now = stamp
        self.state = BusState.REPLAY_FINISHED
        self.sink.enabled = True
        self.engine.publish_diagnostics()
