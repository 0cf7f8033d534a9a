# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The node behind the demo's and the monitor's view: one bridge's topics in, a ``View`` out.

``BridgeWatcher`` is an ordinary ROS node that only subscribes: to ``/diagnostics`` (the
statuses named ``<namespace>/<node>: <device>`` and ``...: CAN bus``) and to each device's
``battery_state``. Devices come from the names given, from those diagnostics names and from
the ROS graph (the BatteryState topics the bridge node publishes). Nothing in the view is
read from the bridge object: the numbers took the same path as for any ROS subscriber.
"""
from __future__ import annotations

from functools import partial
import os
import re
import signal
import sys
import threading
import time
from typing import Any, Callable, Sequence

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from sensor_msgs.msg import BatteryState

from ams_can_bridge.ros.demo_view import (
    device_row, DeviceRow, level_name, to_int, View)

BUS_STATUS = 'CAN bus'  # the name of the bridge's bus status, beside one per device
BATTERY_TYPE = 'sensor_msgs/msg/BatteryState'
DISCOVERY_PERIOD = 1.0  # s between looks at the ROS graph for the bridge's topics
# A device counts as silent after max(stale_after, this many diagnostics periods as seen):
# a bridge publishing /diagnostics every 5 s is not called stopped between two of them.
DIAGNOSTICS_PERIODS = 2.5
# A device row is a ROS name: a status naming anything else ('a/../b', '9x', '') would give a
# topic rclpy refuses, and its exception ended the executor thread: the view froze.
_DEVICE = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')
MAX_ROWS = 64  # the bridge has at most 32 instances: more names are a hostile publisher
MAX_OTHERS = 16  # other bridges' prefixes kept for the "bridges seen" note


class BridgeWatcher(Node):
    """Subscribe to one bridge's battery_state topics and /diagnostics; build the view."""

    def __init__(self, namespace: str = '', bridge_node: str = 'ams_can_bridge',
                 devices: Sequence[str] = (), stale_after: float = 3.0,
                 title: str | None = None, node_name: str | None = None,
                 **kwargs: Any) -> None:
        """
        Watch the bridge ``<namespace>/<bridge_node>``; ``devices``: rows shown from the start.

        ``stale_after``: s without any message about a device (or the bus) before the view
        marks it STALE itself: the bridge does so for a silent device, not for itself.
        """
        super().__init__(node_name or f'ams_can_bridge_monitor_{os.getpid()}',
                         start_parameter_services=False, **kwargs)
        self.namespace = namespace.strip('/')
        self.bridge_node = bridge_node
        self.prefix = f'{self.namespace}/{bridge_node}' if self.namespace else bridge_node
        self.title = title or f'monitor {self.prefix}'
        self.stale_after = stale_after
        self.lock = threading.Lock()
        self.battery: dict[str, Any] = {}
        self.statuses: dict[str, Any] = {}
        self.seen: dict[str, float] = {}  # device -> monotonic time of its last message
        self.rows: list[str] = []         # devices shown, in the order found
        self.bus: Any = None
        self.bus_seen: float | None = None
        self.last_diagnostics: float | None = None
        self.diagnostics_period = 0.0     # as seen between the bridge's last two arrays
        self.others: set[str] = set()     # other bridges' prefixes seen in /diagnostics
        self.skipped = 0                  # statuses not shown (no ROS name, too many rows)
        self.last_skipped = ''            # why the last one was skipped
        self._topic = re.compile(
            rf'^/{re.escape(self.namespace) + "/" if self.namespace else ""}'
            r'([A-Za-z_][A-Za-z0-9_]*)/battery_state$')
        for name in devices:
            self._watch(name)
        self.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, 10)
        self.create_timer(DISCOVERY_PERIOD, self.discover)

    def _watch(self, name: str) -> None:
        """Show a device and subscribe to its battery_state (once); skip a name that cannot."""
        with self.lock:
            if name in self.rows:
                return
            if not _DEVICE.fullmatch(name) or len(self.rows) >= MAX_ROWS:
                self._skip(name, 'no ROS name' if len(self.rows) < MAX_ROWS
                           else f'more than {MAX_ROWS} devices')
                return
            self.rows.append(name)
        topic = f'/{self.namespace}/{name}' if self.namespace else f'/{name}'
        try:
            self.create_subscription(BatteryState, f'{topic}/battery_state',
                                     partial(self._on_battery, name), 10)
        except Exception as exc:  # rclpy refuses the topic: the row stays, without numbers
            with self.lock:
                self._skip(name, f'{type(exc).__name__}')

    def _skip(self, name: str, why: str) -> None:
        """Count a status the view does not show (the caller holds the lock)."""
        self.skipped += 1
        self.last_skipped = f'{name!r}: {why}'

    def _on_battery(self, name: str, msg: BatteryState) -> None:
        with self.lock:
            self.battery[name] = msg
            self.seen[name] = time.monotonic()

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        now = time.monotonic()
        head = f'{self.prefix}: '
        found: list[str] = []
        with self.lock:
            mine = False
            for status in msg.status:
                name = status.name
                if not name.startswith(head):
                    if name.endswith(f': {BUS_STATUS}') and len(self.others) < MAX_OTHERS:
                        self.others.add(name[:-len(BUS_STATUS) - 2])
                    continue
                mine = True
                device = name[len(head):]
                if device == BUS_STATUS:
                    self.bus, self.bus_seen = status, now
                    continue
                if not _DEVICE.fullmatch(device) or (
                        device not in self.rows and len(self.rows) + len(found) >= MAX_ROWS):
                    self._skip(device, 'no ROS name' if _DEVICE.fullmatch(device) is None
                               else f'more than {MAX_ROWS} devices')
                    continue
                self.statuses[device] = status
                self.seen[device] = now
                if device not in self.rows:
                    found.append(device)
            if mine:
                if self.last_diagnostics is not None:
                    self.diagnostics_period = now - self.last_diagnostics
                self.last_diagnostics = now
        for device in found:
            self._watch(device)

    def discover(self) -> None:
        """Watch every device whose BatteryState topic the bridge node publishes."""
        try:
            topics = self.get_publisher_names_and_types_by_node(
                self.bridge_node, '/' + self.namespace)
        except Exception:  # rclpy's NodeNameNonExistentError: the bridge is not up (yet)
            return
        for topic, types in sorted(topics):
            match = self._topic.match(topic)
            if match and BATTERY_TYPE in types:
                self._watch(match.group(1))

    def view(self, uptime: float) -> View:
        """Return the view of the latest messages received."""
        now = time.monotonic()
        with self.lock:
            battery, statuses = dict(self.battery), dict(self.statuses)
            seen, rows, bus, bus_seen = dict(self.seen), list(self.rows), self.bus, self.bus_seen
            others = sorted(self.others - {self.prefix})
            limit = max(self.stale_after, DIAGNOSTICS_PERIODS * self.diagnostics_period)
            skipped, last_skipped = self.skipped, self.last_skipped
        view = View(title=self.title, uptime_s=uptime, last_command=None)
        if skipped:
            view.notes.append(f'{skipped} /diagnostics status(es) skipped, the last '
                              f'{last_skipped}')
        if bus is not None:
            values = {kv.key: kv.value for kv in bus.values}
            view.bus = bus.hardware_id
            view.bus_state = values.get('state', bus.message)
            view.bus_level = level_name(bus.level)
            view.frames_in = to_int(values.get('frames in'))
            view.frames_out = to_int(values.get('frames out'))
            if bus_seen is not None and now - bus_seen > limit:
                view.bus_level = 'STALE'
                view.bus_state = f'no /diagnostics from the bridge for {now - bus_seen:.0f} s'
                view.frames_in = view.frames_out = None
        else:
            view.notes.append(f'waiting for /diagnostics from {self.prefix}')
        if bus is None or view.bus_level == 'STALE':
            if others:
                view.notes.append('bridges seen: ' + ', '.join(others)
                                  + ' (choose with --namespace / --node)')
        for name in rows:
            age = now - seen[name] if name in seen else 0.0
            if age > limit:  # nothing from the bridge: its last numbers are not live
                view.rows.append(DeviceRow(
                    name, name, state='no data', level='STALE',
                    message=f'nothing from the bridge for {age:.0f} s'))
            else:
                view.rows.append(device_row(name, battery.get(name), statuses.get(name)))
        return view


def run_with_ros(argv: Sequence[str], run: Callable[[threading.Event], int]) -> int:
    """
    Start rclpy with argv (the program's name first), return run(stop), shut rclpy down.

    Ctrl-C and SIGTERM set ``stop`` (rclpy's own handlers stay off), so a view ends between
    two draws and tears down in order; a bad ``--ros-args`` part is one line and exit 2.
    """
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    stop = threading.Event()

    def on_signal(signum: int, frame: Any) -> None:
        stop.set()

    old_handlers = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        try:
            rclpy.init(args=list(argv), signal_handler_options=SignalHandlerOptions.NO)
        except Exception as exc:  # rcl's words for a bad --ros-args part
            reason = str(exc).splitlines()[0] if str(exc) else ''
            print(f'{argv[0]}: cannot start ROS ({type(exc).__name__}): {reason}',
                  file=sys.stderr)
            return 2
        return run(stop)
    finally:
        rclpy.try_shutdown()
        for sig, handler in old_handlers.items():
            signal.signal(sig, handler)
