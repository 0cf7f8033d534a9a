"""
Test rig for the command services: a real BridgeNode on python-can's virtual bus.

A separate virtual-bus client captures every frame on the channel (what a CAN analyser
would see); a client node calls the services through ROS, like a user would.
"""
from __future__ import annotations

import contextlib
import itertools
import os
import threading
import time
from typing import Any, Callable, Iterator

import can
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.parameter import Parameter

from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.ros.bridge_node import BridgeNode
from helpers import wait_for

_channels = itertools.count()


def unique_channel(tag: str) -> str:
    """Return a virtual channel name nobody else in this process uses."""
    return f'cmd-{tag}-{os.getpid()}-{next(_channels)}'


class Capture:
    """Every frame seen on a virtual channel, with its monotonic receive time."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface='virtual', channel=channel)
        self.frames: list[tuple[float, Frame]] = []
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            msg = self.bus.recv(0.01)
            if msg is not None and not msg.is_error_frame:
                with self.lock:
                    self.frames.append((time.monotonic(), Frame(
                        msg.arbitration_id, bytes(msg.data), msg.is_extended_id)))

    def close(self) -> None:
        """Stop capturing and close the bus."""
        self._stop.set()
        self._thread.join(2)
        self.bus.shutdown()

    def mark(self) -> int:
        """Return the number of frames so far (a bookmark)."""
        with self.lock:
            return len(self.frames)

    def since(self, mark: int = 0, arbitration_id: int | None = None,
              extended: bool | None = None) -> list[tuple[float, Frame]]:
        """Return frames captured after mark (optionally of one ID / ID kind)."""
        with self.lock:
            frames = self.frames[mark:]
        return [(t, f) for t, f in frames
                if (arbitration_id is None or f.arbitration_id == arbitration_id)
                and (extended is None or f.is_extended_id == extended)]

    def wait_for(self, predicate: Callable[[], Any], timeout: float = 5.0,
                 what: str = 'frames on the bus') -> Any:
        """Wait like the one helper in helpers.py (an AssertionError on timeout)."""
        return wait_for(predicate, timeout, what)


class Rig:
    """Context, bridge node, client node, executor thread and bus capture."""

    def __init__(self, params: dict[str, Any], channel: str | None = None,
                 wait_connected: bool = True) -> None:
        """
        Start the node with these parameter overrides on a fresh virtual channel.

        params may name another bus (can.interface / can.channel); wait_connected=False
        returns while the bridge is still opening it (the capture then sees nothing).
        """
        self.channel = channel or unique_channel('rig')
        self.capture = Capture(self.channel)
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        overrides = {'can.interface': 'virtual', 'can.channel': self.channel, **params}
        self.node = BridgeNode(
            context=self.context,
            parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
        # A virtual bus delivers only to buses open at send time: wait for the bridge's.
        deadline = time.monotonic() + 10.0
        while wait_connected and not self.node.can_io.status().connected:
            assert time.monotonic() < deadline, 'the bridge never opened its virtual bus'
            time.sleep(0.01)
        self.client = rclpy.create_node('command_test_client', context=self.context)
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.client)
        self._spin = threading.Thread(target=self._run, daemon=True)
        self._spin.start()
        self._clients: dict[tuple[str, Any, str], Any] = {}
        self._others: list[Any] = []

    def _run(self) -> None:
        try:
            self.executor.spin()
        except Exception:  # shutdown races end the spin; the test sees the node's state
            pass

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
        """Shut everything down (node first: its commanders stop their threads)."""
        self.executor.shutdown(timeout_sec=2.0)
        self.node.destroy_node()
        self.client.destroy_node()
        for other in self._others:
            other.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._spin.join(2)
        self.capture.close()


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
        for rig in made:
            rig.close()
