"""
A running bridge node for hostile-input tests: executor thread, listener, failure capture.

The bridge and a listener node spin on a MultiThreadedExecutor in a thread, as in the
``bridge`` executable. Everything the node publishes is kept; any exception that escapes
a callback, the executor or any thread is recorded in ``failures`` (tests assert it empty).
"""
from __future__ import annotations

import itertools
import math
import os
import threading
from typing import Any, Callable

from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState

from ams_can_bridge.ros.bridge_node import BridgeNode
from helpers import wait_for

_ids = itertools.count()
# Protocol ranges (PROTOCOLS.md): nothing a frame can carry lies outside these.
INT32_SCALED = 2 ** 31 / 1000  # IVT-S results: int32 mV / mA / mAs
BOUNDS = {
    'voltage': (-INT32_SCALED, INT32_SCALED),  # IVT-S U1 when an AMS uses the shunt
    'current': (-INT32_SCALED, INT32_SCALED),
    'charge': (-INT32_SCALED, INT32_SCALED),
    'capacity': (0.0, 1e6),
    'design_capacity': (0.0, 1e6),
    'percentage': (0.0, 1.0),
    'temperature': (-273.15, 3276.7),  # S16 0.1 degC is the widest temperature encoding
}
CELL_VOLTAGE = (0.0, 65.535)  # uint16 mV is the widest cell encoding
CELL_TEMPERATURE = (-273.15, 3276.7)


def unphysical(msg: BatteryState) -> list[str]:
    """List the fields of msg that are neither NaN nor a value the protocols allow."""
    bad = []

    def check(name: str, value: float, low: float, high: float) -> None:
        if not math.isnan(value) and not (math.isfinite(value) and low <= value <= high):
            bad.append(f'{name}={value!r}')
    for name, (low, high) in BOUNDS.items():
        check(name, getattr(msg, name), low, high)
    for i, value in enumerate(msg.cell_voltage):
        check(f'cell_voltage[{i}]', value, *CELL_VOLTAGE)
    for i, value in enumerate(msg.cell_temperature):
        check(f'cell_temperature[{i}]', value, *CELL_TEMPERATURE)
    if msg.power_supply_status > 4 or msg.power_supply_health > 8 \
            or msg.power_supply_technology > 8:
        bad.append('enum out of range')
    return bad


class LiveBridge:
    """A BridgeNode spinning in a thread, with everything it publishes recorded."""

    def __init__(self, params: dict[str, Any], topics: list[str]) -> None:
        self.failures: list[str] = []
        self._old_hook = threading.excepthook
        threading.excepthook = self._thread_failed
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        n = next(_ids)
        self.ns = f'live_{os.getpid()}_{n}'
        self.node = BridgeNode(
            context=self.context, namespace=self.ns,
            parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        self.hardware_id = self.node.hardware_id
        self.lock = threading.Lock()
        self.battery: dict[str, list[BatteryState]] = {t: [] for t in topics}
        self.diagnostics: list[DiagnosticArray] = []
        self.listener = rclpy.create_node(f'live_listener_{n}', context=self.context)
        for topic in topics:
            self.listener.create_subscription(
                BatteryState, f'/{self.ns}/{topic}/battery_state',
                lambda m, t=topic: self._keep(self.battery[t], m), 1000)
        self.listener.create_subscription(DiagnosticArray, '/diagnostics', self._diag, 100)
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.listener)
        self._spin = threading.Thread(target=self._run, daemon=True)
        self._spin.start()

    def _thread_failed(self, args: Any) -> None:
        self.failures.append(f'thread {args.thread.name}: {args.exc_type.__name__}: '
                             f'{args.exc_value}')

    def _run(self) -> None:
        try:
            self.executor.spin()
        except Exception as exc:  # anything out of a callback ends the spin: record it
            if self.context.ok():
                self.failures.append(f'executor: {type(exc).__name__}: {exc}')

    def _keep(self, where: list, msg: Any) -> None:
        with self.lock:
            where.append(msg)

    def _diag(self, msg: DiagnosticArray) -> None:
        if any(s.hardware_id == self.hardware_id for s in msg.status):
            self._keep(self.diagnostics, msg)

    # --- reading what was published -------------------------------------------------------
    def present_count(self, topic: str) -> int:
        """Return the number of present:true BatteryState messages on topic so far."""
        with self.lock:
            return sum(1 for m in self.battery[topic] if m.present)

    def bus_values(self) -> dict[str, str]:
        """Return the key/values of the newest CAN bus diagnostics status ({} before one)."""
        status = self.bus_status()
        return {kv.key: kv.value for kv in status.values} if status else {}

    def bus_status(self) -> Any:
        """Return the newest CAN bus DiagnosticStatus (None before the first)."""
        with self.lock:
            arrays = list(self.diagnostics[-3:])
        for array in reversed(arrays):
            for status in array.status:
                if status.name.endswith(': CAN bus'):
                    return status
        return None

    def wait(self, predicate: Callable[[], Any], timeout: float = 10.0,
             what: str = 'condition') -> Any:
        """Wait like the one helper in helpers.py, 10 s by default."""
        return wait_for(predicate, timeout, what)

    def close(self) -> None:
        """Stop spinning, destroy the nodes, restore the thread hook."""
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self.listener.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._spin.join(2)
        threading.excepthook = self._old_hook
