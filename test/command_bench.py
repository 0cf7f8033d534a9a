# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ROS-free command harness: a bridge's command side on a python-can virtual bus, no rclpy.

``Bench`` builds what the node builds below ``ros/`` from the same parameter dict a ``Rig``
takes: the devices (``DeviceSet``), the gate, the command side (``engine.commands.Commands``:
every row through the one pipeline, the periodic senders following the gate) and the bus
(``CanIo``, frames to the devices). A call goes ``Commands.call`` -> pipeline -> gate -> bus,
as a service call does in the node, without its ROS adapter. ``Capture`` is the bus-side
analyser shared with the node rig (``command_rig.Rig``).
"""
from __future__ import annotations

import itertools
import os
import threading
import time
from typing import Any, Callable, Mapping, NamedTuple

import can

from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.commands import Commands
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.protocols.common import Frame
from helpers import wait_for
from shared import collecting_logger

_channels = itertools.count()


def unique_channel(tag: str) -> str:
    """Return a virtual channel name nobody else in this process uses."""
    return f'cmd-{tag}-{os.getpid()}-{next(_channels)}'


class Capture:
    """
    Every frame seen on a virtual channel, with its monotonic receive time.

    ``sync()`` proves "nothing was sent" without sleeping: it sends a marker frame on the
    channel and waits until the capture has read it. A virtual bus delivers in send order,
    so every frame the bridge sent before ``sync`` was called is captured by then. Markers
    are not kept in ``frames``.
    """

    MARKER_ID = 0x1FFFFFFE  # 29-bit, used by no device of the bridge

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface='virtual', channel=channel)
        self._marker_bus = can.Bus(interface='virtual', channel=channel)
        self._markers_seen = 0
        self._markers_sent = 0
        self._seen = threading.Condition()
        self.frames: list[tuple[float, Frame]] = []
        # the time each frame was put on the wire (python-can's virtual bus stamps it at
        # the send, wall clock): gaps free of this thread's own scheduling
        self.wire_times: list[float] = []
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            msg = self.bus.recv(0.01)
            if msg is not None and msg.is_extended_id and msg.arbitration_id == self.MARKER_ID:
                with self._seen:
                    self._markers_seen += 1
                    self._seen.notify_all()
            elif msg is not None and not msg.is_error_frame:
                with self.lock:
                    self.frames.append((time.monotonic(), Frame(
                        msg.arbitration_id, bytes(msg.data), msg.is_extended_id)))
                    self.wire_times.append(msg.timestamp)

    def close(self) -> None:
        """Stop capturing and close the bus."""
        self._stop.set()
        self._thread.join(2)
        self._marker_bus.shutdown()
        self.bus.shutdown()

    def sync(self, timeout: float = 5.0) -> None:
        """Send a marker and wait until it is captured: every earlier frame is in by then."""
        with self._seen:
            self._markers_sent += 1
            wanted = self._markers_sent
        self._marker_bus.send(can.Message(arbitration_id=self.MARKER_ID, is_extended_id=True,
                                          data=wanted.to_bytes(4, 'big')))
        with self._seen:
            if not self._seen.wait_for(lambda: self._markers_seen >= wanted, timeout):
                raise AssertionError(f'the capture did not see its marker in {timeout} s')

    def wire_times_of(self, arbitration_id: int, mark: int = 0) -> list[float]:
        """Return the wire times of the frames of one ID captured after mark."""
        with self.lock:
            return [stamp for (_, f), stamp in zip(self.frames[mark:], self.wire_times[mark:])
                    if f.arbitration_id == arbitration_id]

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


def assert_silent_since(bridge: Any, frames_out: int) -> None:
    """
    Assert a Rig's or Bench's bridge sent nothing after its counter read frames_out.

    A marker frame (``Capture.sync``) shows every frame sent before it is captured; the
    bridge's counter and the capture must then both still stand at frames_out.
    """
    bridge.capture.sync()
    captured = [f for _, f in bridge.capture.since(0)]
    assert bridge.frames_out() == len(captured) == frames_out, (
        f'the bridge sent {bridge.frames_out() - frames_out} frame(s) after the call '
        f'returned: {captured[frames_out:]}')


class Answer(NamedTuple):
    """A call's answer, named as a service response's fields are."""

    success: bool
    message: str


class SetResult(NamedTuple):
    """A parameter set's outcome, named as rcl_interfaces' SetParametersResult."""

    successful: bool
    reason: str


class Bench:
    """
    The command side of a bridge on a virtual bus, without ROS (module docstring).

    ``params`` as the node takes them (``devices``, ``commands_allowed``,
    ``commands_enabled``, ``<name>.<key>``, ``can.connect_wait``, ``can.interface`` /
    ``can.channel``); the capture's bus injects frames (``send``).
    """

    def __init__(self, params: Mapping[str, Any], channel: str | None = None,
                 wait_connected: bool = True) -> None:
        """Build the devices, the gate and the command side; open the bus."""
        self.channel = channel or unique_channel('bench')
        self.capture = Capture(self.channel)
        self.log, self.lines = collecting_logger('bench')
        interface = params.get('can.interface', 'virtual')
        bus_channel = params.get('can.channel', self.channel)
        self.gate = CommandGate(f'{interface}:{bus_channel}',
                                allowed=bool(params.get('commands_allowed', False)),
                                connect_wait=float(params.get('can.connect_wait', 5.0)),
                                logger=self.log)
        assert self.gate.start_enabled(bool(params.get('commands_enabled', False))) is None
        self.device_set = DeviceSet(params['devices'],
                                    lambda name, spec: params.get(name, spec.default))
        self.devices = self.device_set.devices
        self.commands = Commands(self.gate, self.devices, self.log,
                                 set_config=self.set_config)
        options = {'options': {'sleep_after_open': 0}} if interface == 'slcan' else {}
        self.io = CanIo(BusConfig(interface=interface, channel=bus_channel,
                                  reconnect_period=float(params.get('can.reconnect_period', 1.0)),
                                  **options),
                        self._on_frame, self.device_set.filters, self.log)
        self.gate.attach_bus(self.io)
        self.io.start()
        if wait_connected:
            wait_for(lambda: self.io.status().connected, 10.0, 'the virtual bus to open')

    def _on_frame(self, arbitration_id: int, data: bytes, extended: bool, stamp: float) -> None:
        self.device_set.handle_frame(arbitration_id, data, extended, stamp)

    def set_config(self, name: str, values: Mapping[str, Any]) -> tuple[bool, str]:
        """Set parameters of one instance all or none, as the node's parameter set does."""
        device = self.devices[name]
        for key, value in values.items():
            reason = device.config_reason(key, value)
            if reason:
                return False, reason
        device.configure(dict(values))
        return True, ''

    # --- calls --------------------------------------------------------------------------
    def call(self, service: str, data: bool | None = None) -> Answer:
        """Call '/<name>/<service>' through the pipeline, as its ROS service would."""
        name, _, suffix = service.strip('/').partition('/')
        return Answer(*self.commands.call(name, suffix, data))

    def call_in_thread(self, service: str, data: bool | None = None) -> dict[str, Any]:
        """Start a call in a thread; the returned dict gets 'response' when it answers."""
        out: dict[str, Any] = {}

        def run() -> None:
            out['response'] = self.call(service, data)
        out['thread'] = threading.Thread(target=run, daemon=True)
        out['thread'].start()
        return out

    def set_param(self, name: str, value: Any) -> SetResult:
        """
        Set commands_enabled, or one '<name>.<key>' of a device.

        The gate tells the command side before this returns; a device's value passes the
        device's own check (rclpy's declared ranges are the node's).
        """
        if name == 'commands_enabled':
            refused = self.gate.set_enabled(bool(value))
            return SetResult(refused is None, refused or '')
        instance, _, key = name.partition('.')
        return SetResult(*self.set_config(instance, {key: value}))

    # --- the bus ----------------------------------------------------------------------------
    def send(self, can_id: int, data: bytes | list[int] = b'', extended: bool = False) -> None:
        """Put a frame on the bridge's virtual bus, as a device would."""
        self.capture.bus.send(can.Message(arbitration_id=can_id, data=bytes(data),
                                          is_extended_id=extended))

    def sent(self, mark: int = 0) -> list[tuple[int, bytes, bool]]:
        """Return (id, data, 29-bit) of every frame captured after mark."""
        return [(f.arbitration_id, f.data, f.is_extended_id) for _, f in self.capture.since(mark)]

    def frames_out(self) -> int:
        """Return how many frames the bridge has sent (its bus counter, counted on send)."""
        return self.io.status().frames_out

    def assert_silent_since(self, frames_out: int) -> None:
        """Assert the bridge sent nothing after its counter read frames_out (a marker)."""
        assert_silent_since(self, frames_out)

    def wait(self, predicate: Callable[[], Any], timeout: float = 10.0,
             what: str = 'condition') -> Any:
        """Wait with helpers.wait_for."""
        return wait_for(predicate, timeout, what)

    def close(self) -> None:
        """Stop the command side and the bus; close the capture (idempotent enough)."""
        self.gate.attach_bus(None)
        self.commands.close()
        self.io.stop()
        self.capture.close()
