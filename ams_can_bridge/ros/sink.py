# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The engine's ROS sink: publishers of BatteryState, arrays, /diagnostics and /clock.

Called on the bus thread (a primary frame) and on the periodic thread; rclpy publishers
are thread-safe. A primary frame's messages are serialized here (diag_cdr.py) and published
raw: rclpy's conversion of message objects was most of a publish. A stale message is built
once per silent spell and only restamped every second (its bytes: the periodic thread's
idle work, bench/README.md "Fifth pass").
"""
from __future__ import annotations

from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32, Float32MultiArray

from ams_can_bridge import cdr
from ams_can_bridge.devices.base import BatteryReport
from ams_can_bridge.engine.core import Arrays, Statuses
from ams_can_bridge.ros import convert, diag_cdr

TELEMETRY_DEPTH = 100  # history of battery_state / array publishers


class RosSink:
    """Publish what the engine emits on the node's topics."""

    def __init__(self, node: Any, arrays: dict[str, list[str]], hardware_id: str,
                 clock: bool, alive: Callable[[], bool],
                 figures: dict[str, tuple[str, ...]] | None = None) -> None:
        """
        Create the publishers: per device (name -> its array suffixes), /diagnostics, /clock.

        ``figures``: name -> the suffixes of its std_msgs/Float32 topics (a pack's).

        ``alive``: False once the node is going away (a publish failing then is dropped).
        """
        self.battery_pubs = {}
        self.array_pubs: dict[str, dict[str, Any]] = {}
        for name, suffixes in arrays.items():
            self.battery_pubs[name] = node.create_publisher(
                BatteryState, f'{name}/battery_state', TELEMETRY_DEPTH)
            self.array_pubs[name] = {
                suffix: node.create_publisher(
                    Float32MultiArray, f'{name}/{suffix}', TELEMETRY_DEPTH)
                for suffix in suffixes}
        self.figure_pubs = {
            name: {suffix: node.create_publisher(Float32, f'{name}/{suffix}', TELEMETRY_DEPTH)
                   for suffix in suffixes}
            for name, suffixes in (figures or {}).items() if suffixes}
        self.diag_pub = node.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.clock_pub = node.create_publisher(Clock, '/clock', 10) if clock else None
        encoder = diag_cdr.DiagnosticsEncoder()
        self._diag_encoder = encoder if encoder.check() else None
        self._raw_telemetry = diag_cdr.check_telemetry()
        self._arrays = cdr.ArrayEncoder()
        self.hardware_id = hardware_id
        self._alive = alive
        self.enabled = False  # lifecycle: publishing only while active
        # name -> (the stale report it was built from, BatteryState, [(publisher, msg)]),
        # the messages raw (bytes) or objects as the primary frames' are
        self._stale: dict[str, tuple[BatteryReport, Any, list[tuple[Any, Any]]]] = {}

    def battery(self, name: str, frame_id: str, report: BatteryReport, arrays: Arrays,
                stamp: float) -> None:
        """Publish a BatteryState and its arrays (raw CDR; a silent one's kept, restamped)."""
        if not self.enabled:
            return
        build = diag_cdr if self._raw_telemetry else convert
        if report.present:
            self._publish_all(name, *self._messages(name, frame_id, report, arrays, build,
                                                    stamp))
            return
        cached = self._stale.get(name)
        if cached is None or cached[0] is not report:
            cached = (report, *self._messages(name, frame_id, report, arrays, build, stamp))
            self._stale[name] = cached
        if build is diag_cdr:  # raw: the kept bytes with a new stamp
            self._publish_all(name, diag_cdr.restamp(cached[1], stamp), cached[2])
            return
        cached[1].header.stamp = convert.stamp_msg(stamp)
        self._publish_all(name, cached[1], cached[2])

    def _messages(self, name: str, frame_id: str, report: BatteryReport, arrays: Arrays,
                  build: Any, stamp: float) -> tuple[Any, list[tuple[Any, Any]]]:
        battery = build.battery_state(report, frame_id, stamp)
        pubs = self.array_pubs[name]
        if build is diag_cdr:  # an unchanged array: its kept bytes (the engine's _emit held)
            encode = self._arrays.encode
            return battery, [(pubs[suffix], encode(f'{name}/{suffix}', rows, cols, data))
                             for suffix, (rows, cols, data) in arrays.items() if suffix in pubs]
        return battery, [(pubs[suffix], build.multi_array(rows, cols, data))
                         for suffix, (rows, cols, data) in arrays.items() if suffix in pubs]

    def _publish_all(self, name: str, battery: Any, arrays: list[tuple[Any, Any]]) -> None:
        self.publish(self.battery_pubs[name], battery)
        for publisher, msg in arrays:
            self.publish(publisher, msg)

    def figures(self, name: str, values: dict[str, float], stamp: float) -> None:
        """Publish the Float32 topics of a pack (no header: its BatteryState has the stamp)."""
        if not self.enabled:
            return
        pubs = self.figure_pubs.get(name, {})
        raw = self._raw_telemetry  # 4 topics at every member report: the message objects
        for suffix, value in values.items():  # were a third of a pack's cost (bench/README)
            if suffix in pubs:
                self.publish(pubs[suffix], diag_cdr.float32(float(value)) if raw
                             else Float32(data=float(value)))

    def diagnostics(self, statuses: Statuses, stamp: float) -> None:
        """Publish one DiagnosticArray (serialized here, published raw when possible)."""
        if not self.enabled:
            return
        if self._diag_encoder is not None:
            msg = self._diag_encoder.encode(stamp, statuses, self.hardware_id)
        else:
            msg = diag_cdr.diagnostic_array(stamp, statuses, self.hardware_id)
        self.publish(self.diag_pub, msg)

    def clock(self, stamp: float) -> None:
        """Publish the replayed log time on /clock."""
        if self.clock_pub is not None and self.enabled:
            self.publish(self.clock_pub, Clock(clock=convert.stamp_msg(stamp)))

    def publishers(self) -> list[Any]:
        """Return every publisher (the node destroys them on cleanup)."""
        pubs = [*self.battery_pubs.values(), self.diag_pub]
        pubs += [p for arrays in self.array_pubs.values() for p in arrays.values()]
        pubs += [p for figures in self.figure_pubs.values() for p in figures.values()]
        return pubs + ([self.clock_pub] if self.clock_pub is not None else [])

    def publish(self, publisher: Any, msg: Any) -> None:
        """Publish from the bus or periodic thread; after a shutdown, drop the message."""
        try:
            publisher.publish(msg)
        except Exception:
            # Ctrl-C / SIGTERM shuts the context down under these threads before the node
            # stops them: 'context is invalid' then means "going away", not a failure.
            if self._alive():
                raise
