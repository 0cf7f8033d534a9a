# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""SimRunner: drives simulated devices on a real python-can bus from one thread."""
from __future__ import annotations

import logging
import threading
import time
from typing import Any, Sequence

import can

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.sim.base import SimDevice

_RX_PER_TICK = 500        # frames taken from the bus per tick: bounded, ticks stay on time
_LOG_EVERY = 5.0          # s: throttle for repeated send / device errors
# s a send may wait for the adapter. Unbounded, a serial port whose other end stops reading
# (a bridge that hangs, a pty nobody drains) blocks the runner in a write for ever, and the
# slcan close at shutdown after it: the simulator could then not be stopped.
SEND_TIMEOUT = 0.1


def open_bus(interface: str, channel: str, bitrate: int = 0,
             options: dict[str, Any] | None = None) -> can.BusABC:
    """Open a python-can bus (bitrate only when > 0; options passed through)."""
    kwargs = dict(options or {})
    if bitrate > 0:
        kwargs['bitrate'] = bitrate
    return can.Bus(interface=interface, channel=channel, **kwargs)


class SimRunner:
    """
    Ticks every device each ``tick_period``, sends their frames, feeds them the bus.

    Time is ``time.monotonic()``. Frames a device returns are sent in order, each send bounded
    by SEND_TIMEOUT; a send error (full TX queue, adapter gone, a serial port nobody reads)
    is counted and logged (throttled), never fatal. Frames read from the bus (at most a
    bounded number per tick) go to every device's on_frame.
    """

    def __init__(self, bus: can.BusABC, devices: Sequence[SimDevice],
                 tick_period: float = 0.002,
                 logger: logging.Logger | None = None) -> None:
        if not tick_period > 0:
            raise ConfigError(f'tick_period = {tick_period}: must be > 0 s')
        self.bus = bus
        self.devices = list(devices)
        self.tick_period = tick_period
        self.frames_sent = 0
        self.frames_received = 0
        self.send_errors = 0
        self.device_errors = 0
        self.receive_errors = 0
        self.last_error = ''
        # (id, extended) each device has sent: for the startup summary and clash warnings.
        self.ids_by_device: dict[str, set[tuple[int, bool]]] = {d.name: set() for d in devices}
        self._log = logger or logging.getLogger('ams_can_bridge.sim')
        self._last_log = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the runner thread (no-op if running)."""
        if self._thread is not None:
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name='sim-runner', daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop and join the thread; the bus stays open (the caller owns it)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    @property
    def running(self) -> bool:
        """Tell whether the runner thread is alive."""
        return self._thread is not None and self._thread.is_alive()

    def step(self, now: float) -> None:
        """Tick every device once at ``now`` and send what they return."""
        for device in self.devices:
            try:
                frames = device.tick(now)
            except Exception as exc:
                self.device_errors += 1
                self._error(f'{device.name}.tick failed: {type(exc).__name__}: {exc}')
                continue
            ids = self.ids_by_device.setdefault(device.name, set())
            for frame in frames:
                ids.add((frame.arbitration_id, frame.is_extended_id))
                self._send(frame)

    def shared_ids(self) -> list[tuple[int, bool]]:
        """Return the (id, extended) pairs sent by more than one device so far."""
        seen: dict[tuple[int, bool], int] = {}
        for ids in self.ids_by_device.values():
            for key in ids:
                seen[key] = seen.get(key, 0) + 1
        return sorted(k for k, n in seen.items() if n > 1)

    def _send(self, frame: Frame) -> None:
        if self._stop.is_set():  # stopping: the rest of this tick's frames would each wait
            return
        try:
            self.bus.send(can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                                      is_extended_id=frame.is_extended_id,
                                      is_fd=len(frame.data) > 8), timeout=SEND_TIMEOUT)
        except Exception as exc:
            self.send_errors += 1
            self._error(f'send 0x{frame.arbitration_id:X} failed: {exc}')
        else:
            self.frames_sent += 1

    def _deliver(self, msg: can.Message, now: float) -> None:
        if msg.is_error_frame or msg.is_remote_frame:
            return
        self.frames_received += 1
        frame = Frame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id)
        for device in self.devices:
            try:
                device.on_frame(frame, now)
            except Exception as exc:
                self.device_errors += 1
                self._error(f'{device.name}.on_frame failed: {type(exc).__name__}: {exc}')

    def _error(self, text: str) -> None:
        self.last_error = text
        now = time.monotonic()
        if now - self._last_log >= _LOG_EVERY:
            self._last_log = now
            self._log.warning('simulator: %s (send errors %d, device errors %d)', text,
                              self.send_errors, self.device_errors)

    def _run(self) -> None:
        next_tick = time.monotonic()
        recv = self.bus.recv
        while not self._stop.is_set():
            now = time.monotonic()
            if now >= next_tick:
                self.step(now)
                next_tick += self.tick_period
                if next_tick < now:  # fell behind (loaded machine): don't burst-catch-up
                    next_tick = now + self.tick_period
            # Wait for frames until the next tick: sleeping and receiving in one call.
            try:
                msg = recv(timeout=max(0.0, next_tick - time.monotonic()))
                count = 0
                while msg is not None:
                    self._deliver(msg, time.monotonic())
                    count += 1
                    if count >= _RX_PER_TICK:
                        break
                    msg = recv(timeout=0.0)
            except Exception as exc:  # adapter gone: keep ticking, try again next tick
                self.receive_errors += 1
                self._error(f'receive failed: {exc}')
                self._stop.wait(self.tick_period)
