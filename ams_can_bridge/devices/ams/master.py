# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The AMS master role without ROS: the car-status heartbeat and the command/wait logic.

The heartbeat (car status, base + 0x005) is one ``PeriodicSender`` (devices/
sender_thread.py): its own thread, a monotonic absolute schedule (slot k at ``start + k *
period``: no drift; a thread late by a period or more skips the missed slots, never a burst).
This module keeps only what the heartbeat carries and what the AMS answers. The counter
increments by one per frame actually put on the bus and wraps 255 -> 0.

The command field carries at most one request at a time (the bus frame has one field):

- ENABLE_SC / ENABLE_TS / ENABLE_DRIVE are carried in every heartbeat until the call
  answers (target state reported, ERROR / CHARGE_ERROR / an error event, abort, timeout),
  then the field goes back to NO_COMMAND. A second command while one waits is refused.
- ABORT is never refused: it replaces whatever is carried in the very next heartbeat (the
  waiting call answers 'aborted') and is carried until the AMS reports IDLE or the timeout
  passes, then NO_COMMAND. A stale ENABLE_* is never sent after an abort.
- SET_BANK_COUNT / SYNC_TIME are one-shot: carried by exactly one heartbeat; the call
  answers once that frame was sent.
- A heartbeat that cannot be sent (bus down) ends the waiting call with failure and the
  reason, and drops the request: the command is never replayed when the bus returns.

Only AMS status frames received *after* the request was first carried count as an answer,
so a state reported before the request can never confirm it.

A state command the AMS cannot carry out from the state it reports now is refused at once,
naming the state it must be in first (``ams_preconditions.py``, doc/protocols.md 1.4): the
seed's car path is IDLE -> SC_ENABLED -> TS_ACTIVE -> DRIVE, one command a step, so
ENABLE_TS needs SC_ENABLED and ENABLE_DRIVE needs TS_ACTIVE. Nothing is carried then (the
heartbeat goes on with NO_COMMAND). While the state is unknown (no status yet, or stale) the
command is carried as before: only the AMS can answer it.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Callable

from ams_can_bridge.devices.ams.preconditions import precondition_refusal
from ams_can_bridge.devices.commands import CommandResult
from ams_can_bridge.protocols.ams import AmsState, CarCommand
from ams_can_bridge.devices.sender_thread import PeriodicSender
from ams_can_bridge.devices.ports import SendFrame
from ams_can_bridge.protocols.common import Frame

TARGETS = {
    CarCommand.ENABLE_SC: AmsState.SC_ENABLED,
    CarCommand.ENABLE_TS: AmsState.TS_ACTIVE,
    CarCommand.ENABLE_DRIVE: AmsState.DRIVE,
    CarCommand.ABORT: AmsState.IDLE,
}
ONE_SHOT = (CarCommand.SET_BANK_COUNT, CarCommand.SYNC_TIME)
ERROR_STATES = (AmsState.ERROR, AmsState.CHARGE_ERROR)


def state_name(code: int) -> str:
    """Return the name of an AMS state code (unknown codes as 'UNKNOWN(n)')."""
    try:
        return AmsState(code).name
    except ValueError:
        return f'UNKNOWN({code})'


@dataclass(frozen=True)
class AmsView:
    """What the master needs to know about the AMS now (read from the device state)."""

    state: int = 0            # AmsState value of the last status frame
    status_seq: int = 0       # +1 per AMS status frame received
    error_seq: int = 0        # +1 per AMS error event (0x014) received
    errors: str = ''          # active error names, human readable ('' = none)
    stale: bool = True

    def describe(self) -> str:
        """Describe state and errors in one line (for service messages)."""
        if self.status_seq == 0:
            return 'AMS state: not reported yet (no AMS status frame received)'
        text = f'AMS state: {state_name(self.state)}'
        text += f', errors: {self.errors}' if self.errors else ', errors: none'
        return text + (' (AMS status is stale)' if self.stale else '')


@dataclass
class _Request:
    command: CarCommand
    started: float
    carried: int = 0                 # heartbeats that carried it
    first_counter: int | None = None  # counter of the first heartbeat that carried it
    status_seq_at_send: int | None = None
    error_seq_at_start: int = 0
    cancelled: str = ''              # reason when replaced (abort) or stopped (gate)
    done: bool = False
    timeout: float = 0.0             # s from started the call waits for its answer


@dataclass(frozen=True)
class HeartbeatStats:
    """Counters of the heartbeat since its last start (diagnostics and the benchmark)."""

    frames_sent: int = 0
    send_failures: int = 0
    missed_slots: int = 0
    last_error: str = ''


class AmsMaster:
    """The heartbeat (one ``PeriodicSender``) and the command requests it carries."""

    label = 'the heartbeat'  # an armed sender (``devices/ports.py``: ``Armed``)

    def __init__(self, encode: Callable[[int, int, int], Frame],
                 send: SendFrame,
                 view: Callable[[], AmsView], period: float = 0.05, bank_count: int = 1,
                 clock: Callable[[], float] = time.monotonic,
                 log: Callable[[str], object] | None = None, name: str = 'ams') -> None:
        """
        Wire the master to its codec, bus and AMS state.

        encode(command, bank_count, counter) builds the car status frame; send(frame)
        returns (ok, message); view() reads the AMS device state; log(line) is told when
        the heartbeat starts and stops, and when it starts carrying a state command (the
        answer is the caller's to log).
        """
        self._encode = encode
        self._view = view
        self._clock = clock
        self._cond = threading.Condition()
        self._switch = threading.Lock()  # start() and stop() one at a time
        self._running = False
        self._period = float(period)
        self.bank_count = int(bank_count)
        self.counter = 0
        self._request: _Request | None = None
        self._carrying: _Request | None = None  # the request of the frame being sent
        self._log = log
        self.name = name
        self.sender = PeriodicSender('ams-heartbeat', 'the heartbeat', self._next_frame, send,
                                     self._period, sent=self._sent, failed=self._failed,
                                     log=log, clock=clock)

    # --- heartbeat thread --------------------------------------------------------------
    @property
    def running(self) -> bool:
        """Tell whether the heartbeat thread is sending."""
        return self._running

    @property
    def thread(self) -> threading.Thread | None:
        """Return the heartbeat's sender, a thread; None while stopped."""
        return self.sender.thread

    @property
    def period(self) -> float:
        """Return the heartbeat period in seconds."""
        return self._period

    @property
    def stats(self) -> HeartbeatStats:
        """Return the heartbeat's counters since its last start."""
        sender = self.sender
        return HeartbeatStats(sender.sent, sender.failed, sender.missed_slots,
                              sender.last_error)

    def start(self) -> bool:
        """Start the heartbeat (False: it runs already)."""
        with self._switch:
            with self._cond:
                if self._running:
                    return False
                self._running = True
            return self.sender.start()

    def stop(self, reason: str = 'the heartbeat stopped') -> bool:
        """Stop the heartbeat (True: it ran); a waiting call answers failure with reason."""
        with self._switch:
            with self._cond:
                was = self._running
                self._running = False
                if self._request is not None:
                    self._request.cancelled = reason
                    self._request = None
                self._cond.notify_all()
            # outside the condition: the sender's hooks take it under the send lock
            self.sender.stop()
            return was

    # --- an armed sender: runs while commands are enabled and the bus is connected -------
    def starts_on_arm(self) -> bool:
        """Tell that arming starts the heartbeat."""
        return True

    def on_arm(self) -> None:
        """Start the heartbeat and say so (once per start)."""
        if self.start() and self._log is not None:
            frame = self._encode(0, self.bank_count, 0)
            self._log(f'{self.name}: heartbeat started: car status 0x{frame.arbitration_id:X} '
                      f'every {self._period * 1000:g} ms')

    def on_disarm(self, shutdown: bool = False) -> None:
        """Stop the heartbeat at once (a waiting call answers why) and say so."""
        if shutdown:
            reason = why = 'the bridge is shutting down'
        else:
            reason = ('commands_enabled was set to false while waiting; the heartbeat '
                      'stopped')
            why = 'commands_enabled is false'
        if self.stop(reason) and self._log is not None:
            self._log(f'{self.name}: heartbeat stopped ({why})')

    def set_period(self, period: float) -> None:
        """Change the heartbeat period from its next slot on; the same period changes nothing."""
        with self._cond:
            if float(period) == self._period:
                return
            self._period = float(period)
        self.sender.set_period(self._period)

    def set_bank_count(self, bank_count: int) -> None:
        """Set the bank count carried by every following heartbeat."""
        with self._cond:
            self.bank_count = int(bank_count)

    def wake(self) -> None:
        """Tell a waiting call that the AMS reported something (a status or error event)."""
        with self._cond:
            self._cond.notify_all()

    def current_command(self) -> CarCommand:
        """Return the command the next heartbeat carries."""
        with self._cond:
            return self._request.command if self._request else CarCommand.NO_COMMAND

    # --- the sender's hooks (its thread) ------------------------------------------------
    def _next_frame(self) -> Frame:
        """Build the slot's heartbeat with the command, bank count and counter of now."""
        with self._cond:
            request = self._request
            command = request.command if request else CarCommand.NO_COMMAND
            bank_count, counter = self.bank_count, self.counter
        self._carrying = request
        return self._encode(int(command), bank_count, counter)

    def _sent(self, frame: Frame, sent_at: float) -> str:
        """Book a heartbeat on the bus (send lock held); the line when a wait begins."""
        request = self._carrying
        # The AMS view is read outside self._cond (it takes the device lock); still under
        # the send lock: a stop()/start() cannot slip a frame with the same counter in.
        view = self._view() if request is not None else None
        with self._cond:
            return self._account(True, '', request, view, sent_at)

    def _failed(self, message: str) -> bool:
        """Book a heartbeat that was not sent (send lock held); the heartbeat goes on."""
        with self._cond:
            self._account(False, message, self._carrying, None, 0.0)
        return True

    def _account(self, ok: bool, message: str, request: _Request | None,
                 view: AmsView | None, sent_at: float) -> str:
        """Book one send attempt (self._cond held); return the line when a wait begins."""
        carried = ''
        if ok:
            if request is not None and not request.done and not request.cancelled:
                assert view is not None  # read by _sent whenever a request was carried
                if request.carried == 0:
                    request.first_counter = self.counter
                    request.status_seq_at_send = view.status_seq
                    if request.command in TARGETS:  # a wait of seconds: say it has begun
                        carried = (f'{self.name}: {request.command.name} carried in the '
                                   f'heartbeat from counter {self.counter}; waiting for '
                                   f'{TARGETS[request.command].name} (up to '
                                   f'{request.started + request.timeout - sent_at:.1f} s)')
                request.carried += 1
                if request.command in ONE_SHOT and self._request is request:
                    self._request = None  # exactly one heartbeat carries it
            self.counter = (self.counter + 1) & 0xFF
        elif request is not None and self._request is request and not request.done:
            # A command is carried by an unbroken run of heartbeats: once one is lost
            # (bus down) the call fails, and nothing stale goes out when the bus returns.
            request.cancelled = (f'the heartbeat carrying it was not sent ({message}); '
                                 'the command was dropped and will not be sent later')
            self._request = None
        self._cond.notify_all()
        return carried

    # --- commands ------------------------------------------------------------------------
    def command(self, command: CarCommand, timeout: float,
                started: float | None = None) -> CommandResult:
        """
        Carry a command in the heartbeat and wait for its answer (see module docstring).

        timeout counts from started (this master's clock; default now), so a caller that
        first waited for the bus keeps timeout as the call's total bound.
        """
        command = CarCommand(command)
        # The AMS view is read outside self._cond (it takes the device lock, which the
        # receive thread holds while it decodes): the heartbeat thread takes the condition
        # at every slot and must never wait behind a lock chain.
        view = self._view()
        error_seq = view.error_seq
        with self._cond:
            if not self._running:
                return CommandResult(False, f'{command.name} not sent: the heartbeat is not '
                                     'running')
            current = self._request
            if command != CarCommand.ABORT and current is not None:
                return CommandResult(False, f'{command.name} refused: {current.command.name} is '
                                     'still in progress (wait for its answer, or call abort)')
            refusal = precondition_refusal(command, view)
            if refusal:
                return CommandResult(False, refusal)
            if current is not None:
                current.cancelled = 'aborted'
            request = _Request(command, self._clock() if started is None else started,
                               error_seq_at_start=error_seq, timeout=timeout)
            self._request = request
            self._cond.notify_all()
        return self._wait(request, timeout)

    def _wait(self, request: _Request, timeout: float) -> CommandResult:
        """
        Wait until the request is answered, taking self._cond only between view reads.

        A view read before the condition is taken is at most older than what the condition
        shows: an AMS status counted as an answer must be newer than the view the heartbeat
        thread booked after the first carrying frame, so an older view can only answer later,
        never wrongly.
        """
        name = request.command.name
        deadline = request.started + timeout
        try:
            while True:
                view = self._view()
                with self._cond:
                    if request.cancelled:
                        return CommandResult(False, f'{name}: {request.cancelled} '
                                             f'({view.describe()})')
                    if request.command in ONE_SHOT and request.carried:
                        return CommandResult(True, f'{name} sent in the heartbeat with counter '
                                             f'{request.first_counter}; {view.describe()}')
                    if request.command in TARGETS and request.carried:
                        answer = self._judge(request, view)
                        if answer is not None:
                            return answer
                    now = self._clock()
                    if now >= deadline:
                        sent = (f'carried in {request.carried} heartbeats' if request.carried
                                else 'never sent (' + (self.sender.last_error or 'no slot') + ')')
                        goal = (f'waiting for {TARGETS[request.command].name}'
                                if request.command in TARGETS else 'waiting to be sent')
                        return CommandResult(False, f'{name}: timeout after {timeout:g} s '
                                             f'{goal}, {sent}; {view.describe()}')
                    # Woken by every heartbeat booked, every AMS status or error event
                    # (``wake``), a cancel or a stop: no polling that competes with the
                    # heartbeat thread for the interpreter.
                    self._cond.wait(deadline - now)
        finally:
            with self._cond:
                request.done = True
                if self._request is request:
                    self._request = None  # back to NO_COMMAND: nothing lingers after an answer

    def _judge(self, request: _Request, view: AmsView) -> CommandResult | None:
        target = TARGETS[request.command]
        name = request.command.name
        fresh = view.status_seq > (request.status_seq_at_send or 0)
        if fresh and view.state == target:
            return CommandResult(True, f'{name}: AMS reports {target.name}; {view.describe()}')
        if request.command == CarCommand.ABORT:
            return None  # abort keeps asking for IDLE whatever happens, until the timeout
        if view.error_seq > request.error_seq_at_start:
            return CommandResult(False, f'{name} failed: the AMS reported an error event; '
                                 f'{view.describe()}')
        if fresh and view.state in ERROR_STATES:
            return CommandResult(False, f'{name} failed: the AMS went to '
                                 f'{state_name(view.state)}; {view.describe()}')
        return None
