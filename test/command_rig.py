# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The test rig: a real BridgeNode on python-can's virtual bus (``rig_factory`` in conftest.py).

A separate virtual-bus client captures every frame on the channel (what a CAN analyser
would see: ``command_bench.Capture``) and injects frames; a client node records what the
bridge publishes and calls its services through ROS, like a user would.
"""
from __future__ import annotations

import contextlib
import threading
import time
import traceback
from typing import Any, Callable, Iterator

import can
from diagnostic_msgs.msg import DiagnosticArray
import rclpy
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState

from ams_can_bridge.ros.bridge_node import BridgeNode
from command_bench import assert_silent_since, Capture, unique_channel
from helpers import wait_for

__all__ = ['battery_topics', 'Capture', 'Rig', 'rigs', 'unique_channel']


def battery_topics(devices: list[str]) -> dict[str, type]:
    """Return the BatteryState topic of each device, for Rig(topics=...)."""
    return {f'{name}/battery_state': BatteryState for name in devices}


class Rig:
    """
    A bridge node on a virtual bus, a client node, an executor and a bus capture.

    The one bridge-on-a-virtual-bus harness of the suite: the client node subscribes to the
    given topics (every message kept in ``msgs``, and /diagnostics arrays naming this
    bridge's hardware), calls services, and the capture's bus injects frames (``send``).
    Anything that escapes a callback, the executor or a thread is kept in ``failures``.
    """

    def __init__(self, params: dict[str, Any], channel: str | None = None,
                 wait_connected: bool = True, topics: dict[str, type] | None = None,
                 namespace: str = '', spin: bool = True, depth: int = 1000) -> None:
        """
        Start the node with these parameter overrides on a fresh virtual channel.

        params may name another bus (can.interface / can.channel); wait_connected=False
        returns while the bridge is still opening it (the capture then sees nothing).
        topics maps topic names (relative to namespace) to message types to record.
        spin=False starts no executor thread: ``wait`` spins the executor while it polls,
        so a test can hold publishing back.
        """
        self.channel = channel or unique_channel('rig')
        self.failures: list[str] = []
        self._closed = False
        self.capture = Capture(self.channel)
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.client = rclpy.create_node('command_test_client', namespace=namespace,
                                        context=self.context)
        self.lock = threading.Lock()
        self.msgs: dict[str, list[Any]] = {'/diagnostics': []}
        self.client.create_subscription(DiagnosticArray, '/diagnostics', self._diag, 100)
        for topic, msg_type in (topics or {}).items():
            self.msgs[topic] = []
            self.client.create_subscription(
                msg_type, topic, lambda m, t=topic: self._keep(t, m), depth)
        # Subscribed first: a replay starts publishing as soon as the bridge exists.
        overrides = {'can.interface': 'virtual', 'can.channel': self.channel, **params}
        self.node = BridgeNode(
            context=self.context, namespace=namespace,
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        self.hardware_id = getattr(self.node, 'hardware_id', '')  # '' until configured
        self._spinning = spin
        self.executor = (MultiThreadedExecutor(num_threads=4, context=self.context) if spin
                         else SingleThreadedExecutor(context=self.context))
        self.executor.add_node(self.node)
        self.executor.add_node(self.client)
        # A virtual bus delivers only to buses open at send time: wait for the bridge's.
        if wait_connected:
            wait_for(lambda: self.node.can_io.status().connected, 10.0,
                     'the bridge to open its virtual bus')
        self._clients: dict[tuple[str, Any, str], Any] = {}
        self._others: list[Any] = []
        self._old_hook = threading.excepthook
        threading.excepthook = self._thread_failed
        self._spin = threading.Thread(target=self._run, daemon=True)
        if spin:
            self._spin.start()

    def _thread_failed(self, args: Any) -> None:
        self.failures.append(f'thread {args.thread.name}: {args.exc_type.__name__}: '
                             f'{args.exc_value}')
        self._old_hook(args)  # the traceback still reaches stderr

    def _run(self) -> None:
        try:
            self.executor.spin()
        except Exception as exc:  # anything out of a callback ends the spin: record it
            if self.context.ok():
                self.failures.append(f'executor: {type(exc).__name__}: {exc}')
                traceback.print_exc()  # as an uncaught exception would: to stderr

    def _keep(self, topic: str, msg: Any) -> None:
        with self.lock:
            self.msgs[topic].append(msg)

    def _diag(self, msg: DiagnosticArray) -> None:
        # other bridges (other tests) may publish on /diagnostics too: keep ours only
        hardware_id = getattr(self.node, 'hardware_id', self.hardware_id)  # once configured
        if any(s.hardware_id == hardware_id for s in msg.status):
            self._keep('/diagnostics', msg)

    @property
    def devices(self) -> dict[str, Any]:
        """Return the node's device instances (as a ``command_bench.Bench`` has them)."""
        return self.node.devices

    # --- the bus ----------------------------------------------------------------------------
    def send(self, can_id: int, data: bytes | list[int] = b'', extended: bool = False,
             **fields: Any) -> None:
        """Put a frame on the bridge's virtual bus (fields: more can.Message arguments)."""
        self.capture.bus.send(can.Message(arbitration_id=can_id, data=bytes(data),
                                          is_extended_id=extended, **fields))

    def frames_out(self) -> int:
        """Return how many frames the bridge has sent (its bus counter, counted on send)."""
        return self.node.can_io.status().frames_out

    def assert_silent_since(self, frames_out: int) -> None:
        """
        Assert the bridge sent nothing after its counter read frames_out; no sleep.

        A marker frame (``Capture.sync``) shows every frame sent before it is captured; the
        bridge's counter and the capture must then both still stand at frames_out. For a
        channel where only the bridge sends (a simulator's frames would be captured too).
        Read frames_out right after the call that must silence the bridge returned; a
        periodic sender's thread is shown ended with ``helpers.assert_ended``.
        """
        assert_silent_since(self, frames_out)

    # --- waiting and reading what was published ---------------------------------------------
    def wait(self, predicate: Callable[[], Any], timeout: float = 10.0,
             what: str = 'condition') -> Any:
        """Wait with helpers.wait_for (spinning the executor when no thread spins it)."""
        if self._spinning:
            return wait_for(predicate, timeout, what)

        def spun() -> Any:
            self.executor.spin_once(timeout_sec=0.05)
            return predicate()
        return wait_for(spun, timeout, what, poll=0.0)

    def messages(self, topic: str) -> list[Any]:
        """Return a copy of the messages received on topic so far."""
        with self.lock:
            return list(self.msgs[topic])

    def last(self, topic: str, predicate: Callable[[Any], bool] = lambda m: True,
             timeout: float = 10.0) -> Any:
        """Wait until a message on topic satisfies predicate; return the newest such."""
        def found() -> Any:
            hits = [m for m in self.messages(topic) if predicate(m)]
            return hits[-1] if hits else None
        return self.wait(found, timeout, f'a matching message on {topic}')

    def status(self, name: str, predicate: Callable[[Any], bool] = lambda s: True,
               timeout: float = 10.0) -> Any:
        """Wait until a DiagnosticStatus named '<node>: name' satisfies predicate."""
        full = f'{self.node.status_prefix()}: {name}'

        def found() -> Any:
            for array in reversed(self.messages('/diagnostics')):
                for status in array.status:
                    if status.name == full and predicate(status):
                        return status
            return None
        return self.wait(found, timeout, f'diagnostics status {full!r}')

    def bus_status(self) -> Any:
        """Return the newest CAN bus DiagnosticStatus (None before the first)."""
        with self.lock:
            arrays = list(self.msgs['/diagnostics'][-3:])
        for array in reversed(arrays):
            for status in array.status:
                if status.name.endswith(': CAN bus'):
                    return status
        return None

    def bus_values(self) -> dict[str, str]:
        """Return the key/values of the newest CAN bus diagnostics status ({} before one)."""
        status = self.bus_status()
        return {kv.key: kv.value for kv in status.values} if status else {}

    def present_count(self, topic: str) -> int:
        """Return the number of present:true BatteryState messages on topic so far."""
        with self.lock:
            return sum(1 for m in self.msgs[topic] if m.present)

    # --- parameters and services ------------------------------------------------------------
    def set_param(self, name: str, value: Any) -> Any:
        """Set one parameter on the node (through its callbacks); return the result."""
        return self.node.set_parameters([Parameter(name, value=value)])[0]

    def other_client(self, name: str) -> Any:
        """Add another client node (a second user of the bridge) to the executor."""
        node = rclpy.create_node(name, context=self.context)
        self.executor.add_node(node)
        self._others.append(node)
        return node

    def call(self, srv_type: Any, name: str, timeout: float = 10.0, client: Any = None,
             **fields: Any) -> Any:
        """Call a service of the node through ROS (from client, a node); return the answer."""
        client_node = client or self.client
        key = (name, srv_type, client_node.get_name())
        if key not in self._clients:
            self._clients[key] = client_node.create_client(srv_type, name)
        client = self._clients[key]
        assert client.wait_for_service(timeout_sec=5.0), f'service {name} is not offered'
        future = client.call_async(srv_type.Request(**fields))
        deadline = time.monotonic() + timeout
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.002)
        assert future.done(), f'{name} did not answer within {timeout} s'
        return future.result()

    def call_in_thread(self, srv_type: Any, name: str, **fields: Any) -> dict[str, Any]:
        """Start a call in a thread; the returned dict gets 'response' when it answers."""
        out: dict[str, Any] = {}

        def run() -> None:
            out['response'] = self.call(srv_type, name, **fields)
        out['thread'] = threading.Thread(target=run, daemon=True)
        out['thread'].start()
        return out

    def close(self) -> None:
        """Shut everything down (node first: its command side stops its threads); idempotent."""
        if self._closed:
            return
        self._closed = True
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self.client.destroy_node()
        for other in self._others:
            other.destroy_node()
        rclpy.try_shutdown(context=self.context)
        if self._spinning:
            self._spin.join(2)
        self.capture.close()
        threading.excepthook = self._old_hook


@contextlib.contextmanager
def rigs() -> Iterator[Callable[..., Rig]]:
    """Yield a maker of Rigs (called as Rig is); close them all on exit."""
    made: list[Rig] = []

    def make(params: dict[str, Any], **kwargs: Any) -> Rig:
        rig = Rig(params, **kwargs)
        made.append(rig)
        return rig
    try:
        yield make
    finally:
        for rig in reversed(made):  # each restores the thread hook it found
            rig.close()
