# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The command gate: every frame the bridge sends passes it (no ROS here).

``CommandGate`` holds ``commands_allowed`` (read-only, from launch) and ``commands_enabled``;
the command pipeline (``transmit``: may wait for a reopening bus, logged per frame) and the
periodic senders (``send_periodic``: never waits, not logged) reach the bus only through it,
and once ``set_enabled(False)`` has returned no frame leaves. Where it sits and its locks:
doc/architecture.md, "Commands"; doc/threads_and_locks.md.
"""
from __future__ import annotations

import logging
import threading
import time
from contextlib import contextmanager
from typing import Callable, Iterator, Protocol

from ams_can_bridge.bus_state import BusStatus, RETRY_STATES
from ams_can_bridge.errors import CanSendError
from ams_can_bridge.protocols.common import Frame

# Commands that may wait for a down bus at once. A waiting call holds an executor thread
# (the bridge runs 4): at most 2 wait, so telemetry, /diagnostics and the parameter
# services (disarming) always keep a thread; a further command fails at once instead.
BUS_WAIT_SLOTS = 2
WAIT_SLICE = 0.05  # s: a bus wait looks at commands_enabled this often
START_SLICE = 0.5  # s: a start waiting for a (re)opening bus looks at commands_enabled this often

Listener = Callable[[bool], None]


class BusPort(Protocol):
    """What the gate needs of the bus (``can_io.CanIo``)."""

    def status(self) -> BusStatus:
        """Return a snapshot of the bus state."""

    def wait_connected(self, timeout: float) -> BusStatus:
        """Wait up to timeout s while the bus is (re)opening; return the status then."""

    def send(self, frame: Frame) -> None:
        """Send one frame; raise CanSendError when the bus or driver refuses."""


def candump_text(frame: Frame) -> str:
    """Return a frame as candump writes it: '305#0102', 29-bit IDs with 8 digits."""
    width = 8 if frame.is_extended_id else 3
    return f'{frame.arbitration_id:0{width}X}#{frame.data.hex().upper()}'


def arming_refused() -> str:
    """Return the reason a commands_enabled = true is refused without commands_allowed."""
    return ('commands_enabled = true refused: commands_allowed is false. commands_allowed is '
            'read-only, set only at launch: start the bridge with commands_allowed: true '
            '(params file or --ros-args -p commands_allowed:=true) to let commands be enabled; '
            'bridge.launch.py commands_allowed:=..., when given, replaces the params file value')


class CommandGate:
    """commands_allowed / commands_enabled, the bus wait, the send locks and the command log."""

    def __init__(self, hardware_id: str, *, allowed: bool, connect_wait: float,
                 logger: logging.Logger, node_name: str = '/ams_can_bridge') -> None:
        """Make a disabled gate; ``attach_bus`` gives it the bus, ``set_enabled`` arms it."""
        self.hardware_id = hardware_id
        self.connect_wait = connect_wait
        self.node_name = node_name
        self.changes = 0  # run-time changes of commands_enabled (diagnostics)
        self._allowed = bool(allowed)
        self._enabled = False
        self._log = logger
        self._bus: BusPort | None = None
        self._bus_waits = threading.BoundedSemaphore(BUS_WAIT_SLOTS)
        # batch: one call's frames (and pacing) are never interleaved with another call's;
        # io: one frame at a time into the driver, the periodic senders included.
        self._batch_lock = threading.RLock()
        self._io_lock = threading.Lock()
        self._listeners: list[Listener] = []
        self._waits_ended = 0  # end_waits(): the bus waits begun before it return
        self._call = threading.local()  # the service a thread is answering (log line)

    # --- state ------------------------------------------------------------------------
    @property
    def allowed(self) -> bool:
        """Tell whether commands may be enabled at all (read-only, set at launch)."""
        return self._allowed

    @property
    def enabled(self) -> bool:
        """Tell whether commands are enabled now."""
        return self._enabled

    def attach_bus(self, bus: BusPort | None) -> None:
        """Send through ``bus`` from now on (None: the bridge is shutting down)."""
        self._bus = bus

    def arming_reason(self, enabled: bool) -> str | None:
        """Return why commands_enabled = enabled would be refused, or None."""
        if enabled and not self._allowed:
            return arming_refused()
        return None

    def set_enabled(self, enabled: bool, how: str = '') -> str | None:
        """
        Enable or disable commands; return the refusal reason (nothing changed) or None.

        A change is logged (WARN, with ``how``) and every listener is told at once, in the
        caller's thread: a disarm stops the periodic senders before this returns, and no
        frame goes out after it returns (a send in flight is waited for).
        """
        enabled = bool(enabled)
        reason = self.arming_reason(enabled)
        if reason:
            self._log.warning(f'refused: {reason}')
            return reason
        with self._io_lock:
            if enabled == self._enabled:
                return None
            self._enabled = enabled
            self.changes += 1
        because = f' ({how})' if how else ''
        if enabled:
            self._log.warning(f'commands_enabled false -> true{because}: commands ENABLED, '
                              'the bridge may transmit')
        else:
            self._log.warning(f'commands_enabled true -> false{because}: commands disabled, '
                              'listen only')
        for listener in list(self._listeners):
            listener(enabled)
        return None

    def start_enabled(self, enabled: bool) -> str | None:
        """Apply commands_enabled given at launch (no change logged, no listener yet)."""
        reason = self.arming_reason(bool(enabled))
        if reason is None:
            self._enabled = bool(enabled)
        return reason

    def add_listener(self, listener: Listener) -> None:
        """Call listener(enabled) whenever commands_enabled changes."""
        self._listeners.append(listener)

    def remove_listener(self, listener: Listener) -> None:
        """Stop calling listener."""
        if listener in self._listeners:
            self._listeners.remove(listener)

    def refusal(self, what: str) -> str:
        """Return the refusal text while commands are disabled (names the parameter(s))."""
        if not self._allowed:
            return (f'commands_enabled is false and commands_allowed is false: to {what}, '
                    'start the bridge with commands_allowed: true (read-only, launch only), '
                    'then set commands_enabled to true; nothing was sent')
        return (f'commands_enabled is false: set the bridge parameter commands_enabled to true '
                f'to {what} ({self._arm_commands()}); '
                'nothing was sent')

    # --- the bus wait -------------------------------------------------------------------
    def wait_for_bus(self, limit: float | None = None) -> tuple[bool, str]:
        """
        Wait for a bus that is opening or reconnecting: (connected, why not) - never raises.

        Waits at most ``connect_wait`` s (and at most ``limit`` s, a state command's own
        timeout); returns early when commands are disabled or ``end_waits`` is called
        meanwhile. Beyond ``BUS_WAIT_SLOTS`` waiting calls a call is refused at once.
        """
        bus = self._bus
        if bus is None:
            return False, f'CAN bus {self.hardware_id} is closed: the bridge is shutting down'
        status = bus.status()
        if status.connected:
            return True, ''
        wait = self.connect_wait if limit is None else min(self.connect_wait, limit)
        if wait > 0 and status.state in RETRY_STATES:
            if not self._bus_waits.acquire(blocking=False):
                reason = f': {status.reason}' if status.reason else ''
                return False, (f'CAN bus {self.hardware_id} is not connected ({status.state}'
                               f'{reason}) and {BUS_WAIT_SLOTS} commands already wait for it: '
                               'try again later')
            try:
                return self._wait_for_bus(bus, status, wait, limit)
            finally:
                self._bus_waits.release()
        return self._wait_for_bus(bus, status, wait, limit)

    def end_waits(self) -> None:
        """End every bus wait in flight now (a lifecycle transition ends the calls first)."""
        self._waits_ended += 1

    def bus_waiters(self) -> int:
        """Return how many calls wait for the bus now."""
        return BUS_WAIT_SLOTS - self._bus_waits._value

    def _wait_for_bus(self, bus: BusPort, status: BusStatus, wait: float,
                      limit: float | None) -> tuple[bool, str]:
        deadline = time.monotonic() + wait
        ended = self._waits_ended
        while status.state in RETRY_STATES and self._enabled:
            if self._waits_ended != ended:
                return False, 'the call was ended while waiting for the CAN bus'
            left = deadline - time.monotonic()
            if left <= 0:
                break
            # in slices, so that switching commands_enabled off ends the wait at once
            status = bus.wait_connected(min(left, WAIT_SLICE))
            if status.connected:
                return True, ''
        if not self._enabled:
            return False, 'commands_enabled was set to false while waiting for the CAN bus'
        reason = f': {status.reason}' if status.reason else ''
        waited = ''
        if status.state in RETRY_STATES:
            waited = (f' after waiting {wait:g} s (can.connect_wait {self.connect_wait:g} s'
                      + (f', command timeout {limit:g} s)' if limit is not None else ')')
                      if wait > 0 else ' (can.connect_wait is 0: commands do not wait)')
        return False, (f'CAN bus {self.hardware_id} is not connected ({status.state}{reason})'
                       f'{waited}')

    # --- sending --------------------------------------------------------------------------
    @contextmanager
    def batch(self) -> Iterator[None]:
        """Hold the batch lock: the frames sent meanwhile are one call's, in order."""
        with self._batch_lock:
            yield

    @contextmanager
    def calling(self, source: str) -> Iterator[None]:
        """Name the service this thread answers meanwhile (``transmit`` logs with it)."""
        outer = getattr(self._call, 'source', None)
        self._call.source = source
        try:
            yield
        finally:
            self._call.source = outer

    def transmit(self, frame: Frame, *, wait: bool = True,
                 source: str | None = None) -> tuple[bool, str]:
        """
        Send one frame of a call if commands are enabled; (ok, message) - never raises.

        The frame is logged at INFO with its source (the service a call answers, or
        ``source``), the frame (candump's ID#data) and the outcome.
        """
        ok, message = self._transmit(frame, wait)
        source = source or getattr(self._call, 'source', None)
        if source is not None:
            outcome = 'sent' if ok else f'NOT sent: {message}'
            self._log.info(f'{source}: {candump_text(frame)} {outcome}')
        return ok, message

    def send_periodic(self, frame: Frame) -> tuple[bool, str]:
        """Send one frame of a periodic sender: the gate, no wait, no batch, no log line."""
        return self._send(frame)

    def start_when_connected(self, start: Callable[[], None]) -> PendingStart:
        """
        Call ``start`` (a periodic sender's) once the bus is connected; return its hold.

        At once when it is connected, else on a thread of its own as soon as it is; never
        once commands are disabled or the returned ``PendingStart`` is cancelled.
        """
        pending = PendingStart(self, start)
        if not pending.fire():
            threading.Thread(target=pending.wait, name='start-when-connected',
                             daemon=True).start()
        return pending

    def bus_connected(self) -> bool:
        """Tell whether the bus is attached and connected now."""
        bus = self._bus
        return bus is not None and bus.status().connected

    def _transmit(self, frame: Frame, wait: bool) -> tuple[bool, str]:
        if not self._enabled:
            return False, self._disabled()
        if wait:  # outside the batch lock: calls wait for the bus side by side
            ok, message = self.wait_for_bus()
            if not ok:
                return False, message
        with self._batch_lock:
            return self._send(frame)

    def _disabled(self) -> str:
        return ('commands are disabled: set the parameter commands_enabled to true '
                f'({self._arm_commands()}) to transmit')

    def _arm_commands(self) -> str:
        """Return how to arm this bridge: bridgectl (no ROS install needed), or ros2."""
        namespace, _, node = self.node_name.rpartition('/')
        options = ''.join([f' --namespace {namespace.strip("/")}' if namespace.strip('/')
                           else '', f' --node {node}' if node != 'ams_can_bridge' else ''])
        return (f'bridgectl{options} arm, or ros2 param set {self.node_name} '
                'commands_enabled true')

    def _send(self, frame: Frame) -> tuple[bool, str]:
        bus = self._bus
        if bus is None:
            return False, f'CAN bus {self.hardware_id} is closed: the bridge is shutting down'
        try:
            with self._io_lock:  # the gate is looked at under the lock a disarm takes
                if not self._enabled:
                    return False, self._disabled()
                bus.send(frame)  # every driver failure arrives as CanSendError
        except CanSendError as exc:
            return False, f'CAN send failed on {self.hardware_id}: {exc}'
        return True, f'sent 0x{frame.arbitration_id:X} [{frame.data.hex(" ").upper()}]'


class PendingStart:
    """
    A periodic sender's start held until the bus is connected (``start_when_connected``).

    ``fire`` starts it if the bus is connected and commands are enabled, at most once;
    after ``cancel`` returns it never starts. Both take one lock, so a disarm (cancel, then
    stop the sender) can never be followed by a start.
    """

    def __init__(self, gate: CommandGate, start: Callable[[], None]) -> None:
        """Hold ``start`` for ``gate``'s bus; nothing runs until ``fire``."""
        self._gate = gate
        self._start = start
        self._lock = threading.Lock()
        self.done = False  # started or cancelled

    def fire(self) -> bool:
        """Start now if the bus is connected; True once started, cancelled or disabled."""
        with self._lock:
            if not self.done and self._gate.enabled:
                if not self._gate.bus_connected():
                    return False
                self._start()
            self.done = True
            return True

    def cancel(self) -> None:
        """Never start from now on (a start under way has finished when this returns)."""
        with self._lock:
            self.done = True

    def wait(self) -> None:
        """Wait for the bus to connect, then start (the thread of ``start_when_connected``)."""
        while not self.fire():
            bus = self._gate._bus
            status = bus.status() if bus is not None else None
            if bus is not None and status is not None and status.state in RETRY_STATES:
                bus.wait_connected(START_SLICE)  # returns as soon as it is connected
            else:
                time.sleep(WAIT_SLICE)  # not attached or not started yet (configure)
