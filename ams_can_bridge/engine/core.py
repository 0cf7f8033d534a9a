# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The engine: every "what to emit, and when" decision of the bridge, without ROS.

``Engine.on_frame`` takes every frame and emits a primary frame's snapshot into the
``Sink``; the periodic decisions (stale messages, /diagnostics, the bus report) run on the
clock its caller gives: the live node's ``TimerThread``, or log2bag's ``Schedule``, so a
bag holds what the live bridge publishes. The flow: doc/architecture.md, "Data".

Threads (live): ``on_frame`` runs on the bus thread, the periodic work on another. A
device's BatteryState is emitted under ``_emit``: a staleness check and its ``present:
false`` message are one step, so a fresh ``present: true`` can never be overtaken by a
stale message decided just before it (test_engine.py).
"""
from __future__ import annotations

import logging
import math
import threading
import time
from typing import Any, Callable, Protocol

from ams_can_bridge import reports
from ams_can_bridge.bus_state import BusStatus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.base import BatteryReport, Device, DiagnosticReport
from ams_can_bridge.devices.config import DeviceConfig
from ams_can_bridge.devices.pack.device import PackDevice

Arrays = dict[str, tuple[int, int, list[float]]]
Statuses = list[tuple[str, DiagnosticReport]]

MALFORMED_LOG_PERIOD = 5.0  # s between malformed-frame log lines per device
STALE_PUBLISH_PERIOD = 1.0  # s, battery_state present:false while stale
WATCH_PERIOD = 0.2  # s, how fast bus state / staleness transitions are noticed
# s: a device that keeps taking frames has its level rebuilt at most this often by the watch
# (a report is the watch's largest cost, and at full load every device changes between two
# watches; bench/README.md). A staleness change and the first frame after a quiet spell are
# still noticed at the next watch.
LEVEL_RECHECK_PERIOD = 0.5


class Sink(Protocol):
    """Where the engine's messages go: the ROS node, a bag, a test's list."""

    def battery(self, name: str, frame_id: str, report: BatteryReport, arrays: Arrays,
                stamp: float) -> None:
        """
        Emit a device's BatteryState (header stamp ``stamp``) and its arrays.

        A repeated stale message passes the very same ``report`` object again: a sink may
        keep what it built from it and only restamp it.
        """

    def diagnostics(self, statuses: Statuses, stamp: float) -> None:
        """Emit one DiagnosticArray of (full status name, report)."""

    def figures(self, name: str, values: dict[str, float], stamp: float) -> None:
        """Emit a pack's std_msgs/Float32 topics ``<name>/<suffix>`` (at ``stamp``)."""

    def clock(self, stamp: float) -> None:
        """Emit the replayed log time (/clock)."""


class Engine:
    """Frames in, messages out: device snapshots, stale messages, diagnostics, bus report."""

    def __init__(self, device_set: DeviceSet, sink: Sink, *, status_prefix: str,
                 interface: str, bus_status: Callable[[], BusStatus],
                 now: Callable[[], float], monotonic: Callable[[], float] = time.monotonic,
                 bus_values: Callable[[], dict[str, str]] | None = None,
                 on_bus_status: Callable[[BusStatus], None] | None = None,
                 logger: logging.Logger | None = None) -> None:
        """
        Wire the engine; nothing is emitted until frames or the periodic calls come.

        ``now``: the stamp of a message no frame stamps (wall time live, the log's time in
        a replay or offline); ``monotonic``: the clock of the level cache and the malformed
        log throttle; ``bus_values``: extra values of the CAN bus report (the node's
        command keys); ``on_bus_status``: sees every bus status the watch takes (logging).
        """
        self.device_set = device_set
        self.devices = device_set.devices
        self.sink = sink
        self.status_prefix = status_prefix
        self.interface = interface
        self.bus_status = bus_status
        self.now = now
        self.monotonic = monotonic
        self.bus_values = bus_values
        self.on_bus_status = on_bus_status
        self.log = logger or logging.getLogger('ams_can_bridge.engine')
        self._emit = threading.Lock()  # a device's staleness check + its message: one step
        self._levels: dict[str, int] = {}
        # name -> (device revision, stale, level, monotonic time of the rebuild)
        self._level_cache: dict[str, tuple[int, bool, int, float]] = {}
        # name -> (device revision, stale report, stale arrays): built once while silent
        self._stale_msgs: dict[str, tuple[int, BatteryReport, Arrays]] = {}
        self._malformed_logged: dict[str, tuple[int, float]] = {}
        self._stale = {name: True for name in self.devices}
        self._heard: set[str] = set()
        self._clock_sent = math.nan
        # member name -> the packs it belongs to: each member report feeds them (packs.md)
        self._packs: dict[str, list[PackDevice]] = {}
        for device in self.devices.values():
            if isinstance(device, PackDevice):
                for member in device.members:
                    self._packs.setdefault(member.name, []).append(device)

    # --- bus thread -------------------------------------------------------------------------
    def on_frame(self, arbitration_id: int, data: bytes, is_extended_id: bool,
                 stamp: float) -> None:
        """Decode one frame; emit the BatteryState of every device it was primary for."""
        primaries = self.device_set.handle_frame(arbitration_id, data, is_extended_id, stamp)
        if primaries:
            with self._emit:
                for device in primaries:
                    self._emit_snapshot(device, stamp)

    def _emit_snapshot(self, device: Device, stamp: float) -> None:
        report, arrays = device.snapshot()
        if not report.present:
            arrays = _nan_arrays(arrays)
        elif math.isfinite(report.stamp):
            stamp = report.stamp
        name = device.name
        self.sink.battery(name, _frame_id(device), report, arrays, stamp)
        if name in self._packs:
            self._feed_packs(name, report, stamp)

    def _feed_packs(self, name: str, report: BatteryReport, stamp: float) -> None:
        """Give a member's emitted report to its packs; emit what they make of it (_emit held)."""
        for pack in self._packs[name]:
            out = pack.take(name, report, stamp)
            self.sink.battery(pack.name, _frame_id(pack), out.report, {}, stamp)
            self.sink.figures(pack.name, pack.figures(out), stamp)
            for event in out.raised:
                log = (self.log.error if event.severity.name == 'MSL'
                       else self.log.warning if event.severity.name == 'RSL' else self.log.info)
                log('%s: %s', pack.name, event.describe())

    # --- periodic work ------------------------------------------------------------------------
    def publish_stale(self) -> None:
        """Emit ``present: false`` for every silent device (every STALE_PUBLISH_PERIOD)."""
        for name, device in self.devices.items():
            if device.is_stale():
                self._emit_stale(name)

    def _emit_stale(self, name: str) -> None:
        device = self.devices[name]
        with self._emit:
            revision = device.revision
            cached = self._stale_msgs.get(name)
            if cached is None or cached[0] != revision:
                report, arrays = device.snapshot()
                # A frame may have come since is_stale() said so: that frame emitted itself.
                if report.present:
                    return
                # Nothing in a silent device's message changes until a frame or a parameter
                # does (its revision): built once, emitted again every second (idle CPU).
                cached = (revision, report, _nan_arrays(arrays))
                self._stale_msgs[name] = cached
            # "Nothing heard, as of now": stamped when emitted, never with the last frame's
            # time, which would make a silent device look as if it had just been repeated.
            now = self.now()
            self.sink.battery(name, _frame_id(device), cached[1], cached[2], now)
            if name in self._packs:
                self._feed_packs(name, cached[1], now)

    def statuses(self) -> Statuses:
        """Return every device's report and the CAN bus's, named as the bridge names them."""
        statuses = []
        for name, device in self.devices.items():
            revision, stale = device.revision, device.is_stale()
            report = device.diagnostic_report()
            self._level_cache[name] = (revision, stale, int(report.level), self.monotonic())
            statuses.append((name, report))
        statuses.append(('CAN bus', self.bus_report()))
        self._levels = {name: int(report.level) for name, report in statuses}
        return [(f'{self.status_prefix}: {name}', report) for name, report in statuses]

    def publish_diagnostics(self) -> None:
        """Emit one DiagnosticArray: every device plus the CAN bus."""
        stamp = self.now()
        self.sink.diagnostics(self.statuses(), stamp)

    def bus_report(self, status: BusStatus | None = None) -> DiagnosticReport:
        """Return the CAN bus report: the bus state and counters, the devices' malformed."""
        status = status or self.bus_status()
        malformed = sum(d.frames_malformed for d in self.devices.values())
        report = reports.bus_report(status, malformed, self.interface)
        if self.bus_values is not None:
            report.values.update(self.bus_values())
        return report

    def _device_level(self, name: str, stale: bool | None = None) -> int:
        """Return a device's diagnostic level, rebuilding its report only after a change."""
        device = self.devices[name]
        revision = device.revision
        if stale is None:
            stale = device.is_stale()
        cached = self._level_cache.get(name)
        now = self.monotonic()
        if (cached is None or cached[1] != stale
                or (cached[0] != revision and now - cached[3] >= LEVEL_RECHECK_PERIOD)):
            cached = (revision, stale, int(device.diagnostic_level()), now)
            self._level_cache[name] = cached
        return cached[2]

    def watch(self) -> None:
        """Notice staleness, malformed frames and level changes (every WATCH_PERIOD)."""
        status = self.bus_status()
        if self.on_bus_status is not None:
            self.on_bus_status(status)
        now = self.monotonic()
        levels = self._levels  # as last published; {} before the first /diagnostics
        # One pass over the devices: 5 times a second, each wake-up's code runs cold
        # (bench/README.md, "Fifth pass"). Once a level differs the others are not asked:
        # the publish that follows builds every report anew.
        changed = levels.get('CAN bus') != int(reports.bus_level(status))
        for name, device in self.devices.items():
            stale = device.is_stale()
            if stale != self._stale[name]:
                self._stale[name] = stale
                if stale:
                    self.log.warning('%s: no status frame for %g s: STALE', name,
                                     device.stale_timeout)
                    self._emit_stale(name)
                elif name in self._heard:
                    self.log.info('%s: receiving again', name)
                else:
                    self.log.info('%s: first status frame received', name)
                self._heard.add(name)
            count = device.frames_malformed
            if count:
                logged, at = self._malformed_logged.get(name, (0, -math.inf))
                if count > logged and now - at >= MALFORMED_LOG_PERIOD:
                    self._malformed_logged[name] = (count, now)
                    self.log.warning('%s: %d malformed frame(s) so far, dropped; last: %s',
                                     name, count, device.last_malformed)
            if not changed and self._device_level(name, stale) != levels.get(name):
                changed = True
        if changed:
            self.publish_diagnostics()

    def publish_clock(self, stamp: float) -> None:
        """Emit the replayed log time when it moved (every CLOCK_PERIOD of a replay)."""
        if math.isfinite(stamp) and stamp != self._clock_sent:
            self._clock_sent = stamp
            self.sink.clock(stamp)

    def schedule(self, diagnostics_period: float) -> list[tuple[float, Callable[[], None]]]:
        """Return the periodic work as (period, call), in the order it runs when due."""
        return [(diagnostics_period, self.publish_diagnostics),
                (STALE_PUBLISH_PERIOD, self.publish_stale),
                (WATCH_PERIOD, self.watch)]

    def quiet_horizon(self) -> float:
        """Return how long a silent bus changes what is emitted (every device gone stale)."""
        timeouts = [device.stale_timeout for device in self.devices.values()]
        return max(timeouts, default=0.0) + 2 * WATCH_PERIOD


class Schedule:
    """The engine's periodic work driven by a clock the caller moves (a log's time)."""

    def __init__(self, tasks: list[tuple[float, Callable[[], None]]],
                 set_now: Callable[[float], None], horizon: float = math.inf) -> None:
        """
        Take (period, call) pairs; ``set_now`` moves the engine's clock before each call.

        ``horizon``: how long into a gap (no stamp) the grid is run (``run_until``).
        """
        # [next run, period, call]: a list, moved in place
        self.tasks: list[list[Any]] = [[math.nan, period, call] for period, call in tasks]
        self.set_now = set_now
        self.horizon = horizon
        self.started = False
        self.last = math.nan  # the latest stamp run to
        self._longest = max((period for period, _ in tasks), default=0.0)
        # the first task's next run: a stamp before it runs nothing (most frames of a log;
        # run_until's caller may test it to skip the call)
        self.due = math.inf

    def start(self, now: float) -> None:
        """Start the grid at ``now``: each task first runs one period later."""
        self.started = True
        self.last = now
        for task in self.tasks:
            task[0] = now + task[1]
        self.due = min((task[0] for task in self.tasks), default=math.inf)

    def run_until(self, stamp: float) -> None:
        """
        Run every task due up to ``stamp``, each at its own moment, in order.

        A gap longer than ``horizon`` after the last stamp (a logger that paused, a car
        parked overnight, a timestamp years off) is not worked through period by period:
        the tasks run until ``horizon`` into it (what a silence changes has been emitted by
        then) and skip the rest of it, each keeping its phase. A stamp earlier than the last
        by more than the longest period (logs put one after another) starts the grid again.
        """
        if not self.started:
            return
        if stamp < self.last - self._longest:
            self.start(stamp)
            return
        if stamp < self.due:  # nothing due (the loop below would run nothing)
            if stamp > self.last:
                self.last = stamp
            return
        end = min(stamp, self.last + self.horizon)
        while True:
            task = min(self.tasks, key=lambda t: t[0])  # the first of equals: list order
            if task[0] > end:
                break
            self.set_now(task[0])
            task[0] += task[1]
            task[2]()
        if stamp > end:  # the rest of a long gap: each task's first slot after it
            for task in self.tasks:
                if task[0] < stamp:
                    task[0] += math.ceil((stamp - task[0]) / task[1]) * task[1]
        self.last = max(self.last, stamp)
        self.due = min((task[0] for task in self.tasks), default=math.inf)


def _nan_arrays(arrays: Arrays) -> Arrays:
    """Return the arrays of a silent device: NaN, not the last values."""
    return {suffix: (rows, cols, [math.nan] * len(data))
            for suffix, (rows, cols, data) in arrays.items()}


def _frame_id(device: Device) -> str:
    """Return a device's header.frame_id (a value every configuration class has)."""
    config: DeviceConfig = device.config  # any device type's: the common values are checked
    return config.frame_id
