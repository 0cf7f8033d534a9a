"""
The AMS master role without ROS: the car-status heartbeat and the command/wait logic.

The heartbeat (car status, base + 0x005) runs on its own thread from a monotonic absolute
schedule: slot k is due at ``start + k * period``. Sleeping to an absolute time cannot drift;
when the thread is late by a whole period or more (machine overloaded), the missed slots are
skipped (never sent in a burst) and counted. The counter increments by one per frame actually
put on the bus and wraps 255 -> 0.

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

import math
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

from ams_can_bridge.devices.ams_preconditions import precondition_refusal
from ams_can_bridge.errors import ParamError
from ams_can_bridge.protocols.ams import AmsState, CarCommand
from ams_can_bridge.devices.ports import SendFrame
from ams_can_bridge.protocols.common import Frame

POLL_S = 0.005  # waiting calls re-check the AMS state this often (a few ms)

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


@dataclass(frozen=True)
class CommandResult:
    """The answer of a command call."""

    success: bool
    message: str


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


@dataclass
class HeartbeatStats:
    """Counters of the heartbeat thread (diagnostics and the benchmark)."""

    frames_sent: int = 0
    send_failures: int = 0
    missed_slots: int = 0
    last_error: str = ''
    send_times: list[float] = field(default_factory=list)  # only when record=True


class HeartbeatSchedule:
    """Absolute monotonic slots: slot k at start + k * period, late slots skipped."""

    def __init__(self, period: float, start: float) -> None:
        if not period > 0:
            raise ParamError(f'heartbeat period {period!r} must be > 0')
        self.period = period
        self.start = start
        self.k = 0

    def due(self) -> float:
        """Return the time of the next slot."""
        return self.start + self.k * self.period

    def take(self, now: float) -> int:
        """Consume the slot due at or before now; return how many slots were skipped."""
        latest = int(math.floor((now - self.start) / self.period + 1e-9))
        skipped = max(0, latest - self.k)
        self.k = max(self.k, latest) + 1
        return skipped

    def rebase(self, period: float, now: float) -> None:
        """Change the period from now on (first slot of the new period: one period ahead)."""
        if not period > 0:
            raise ParamError(f'heartbeat period {period!r} must be > 0')
        last = self.start + (self.k - 1) * self.period if self.k else now
        self.period = period
        self.start = max(last + period, now)
        self.k = 0


class AmsMaster:
    """Heartbeat thread + command requests; the ROS layer only wires services to it."""

    def __init__(self, encode: Callable[[int, int, int], Frame],
                 send: SendFrame,
                 view: Callable[[], AmsView], period: float = 0.05, bank_count: int = 1,
                 clock: Callable[[], float] = time.monotonic, record: bool = False,
                 log: Callable[[str], object] | None = None, name: str = 'ams') -> None:
        """
        Wire the master to its codec, bus and AMS state.

        encode(command, bank_count, counter) builds the car status frame; send(frame)
        returns (ok, message); view() reads the AMS device state; log(line) is told when
        the heartbeat starts carrying a state command (the answer is the caller's to log).
        """
        self._encode = encode
        self._send = send
        self._view = view
        self._clock = clock
        self._cond = threading.Condition()
        self._send_lock = threading.Lock()  # stop() returns only after an in-flight send
        self._wake = threading.Event()  # wakes the heartbeat thread before its slot
        self._thread: threading.Thread | None = None
        self._running = False
        self._generation = 0  # a thread from before a stop/start never sends again
        self._period = float(period)
        self._schedule: HeartbeatSchedule | None = None
        self.bank_count = int(bank_count)
        self.counter = 0
        self.stats = HeartbeatStats()
        self._record = record
        self._request: _Request | None = None
        self._log = log
        self.name = name

    # --- heartbeat thread --------------------------------------------------------------
    @property
    def running(self) -> bool:
        """Tell whether the heartbeat thread is sending."""
        return self._running

    @property
    def period(self) -> float:
        """Return the heartbeat period in seconds."""
        return self._period

    def start(self) -> None:
        """Start the heartbeat (no-op when running)."""
        with self._cond:
            if self._running:
                return
            self._running = True
            self._generation += 1
            self._schedule = HeartbeatSchedule(self._period, self._clock())
            self._thread = threading.Thread(target=self._run, args=(self._generation,),
                                            name='ams-heartbeat', daemon=True)
            self._thread.start()

    def stop(self, reason: str = 'the heartbeat stopped') -> None:
        """Stop the heartbeat; a waiting call answers failure with reason, field reset."""
        with self._cond:
            thread = self._thread
            self._running = False
            self._thread = None
            if self._request is not None:
                self._request.cancelled = reason
                self._request = None
            self._cond.notify_all()
        self._wake.set()
        with self._send_lock:
            pass  # a frame being sent right now is on the bus before stop() returns
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2.0)

    def set_period(self, period: float) -> None:
        """Change the heartbeat period at run time."""
        with self._cond:
            self._period = float(period)
            if self._schedule is not None:
                self._schedule.rebase(self._period, self._clock())
            self._cond.notify_all()
        self._wake.set()

    def set_bank_count(self, bank_count: int) -> None:
        """Set the bank count carried by every following heartbeat."""
        with self._cond:
            self.bank_count = int(bank_count)

    def current_command(self) -> CarCommand:
        """Return the command the next heartbeat carries."""
        with self._cond:
            return self._request.command if self._request else CarCommand.NO_COMMAND

    def _alive(self, generation: int) -> bool:
        return self._running and self._generation == generation

    def _run(self, generation: int) -> None:
        while True:
            # Sleep on an event of the thread's own, not on self._cond: waiting calls take the
            # condition every few ms, and waking into a held lock makes the heartbeat late.
            with self._cond:
                if not self._alive(generation):
                    return
                now = self._clock()
                schedule = self._schedule
                assert schedule is not None  # made by start() before the thread
                wait = schedule.due() - now
                if wait <= 0:
                    self.stats.missed_slots += schedule.take(now)
                    request = self._request
                    command = request.command if request else CarCommand.NO_COMMAND
                    bank_count, counter = self.bank_count, self.counter
            if wait > 0:
                self._wake.wait(wait)
                self._wake.clear()  # state changes come before set(): re-read it now
                continue
            try:
                frame = self._encode(int(command), bank_count, counter)
            except Exception as exc:  # a bad bank count must not kill the thread
                frame = None
                self.stats.last_error = f'cannot build the heartbeat: {exc}'
            # send outside the condition: a slow bus must not block service calls or abort
            with self._send_lock:
                if not self._alive(generation):
                    return
                ok, message = ((False, self.stats.last_error) if frame is None
                               else self._send(frame))
                sent_at = self._clock()
                view = self._view() if ok and request is not None else None
                # still under the send lock: a stop()/start() cannot slip a frame with the
                # same counter in between this send and its counter increment
                with self._cond:
                    carried = self._account(ok, message, request, view, sent_at)
            if carried and self._log is not None:  # outside the locks: the next slot waits
                self._log(carried)

    def _account(self, ok: bool, message: str, request: _Request | None,
                 view: AmsView | None, sent_at: float) -> str:
        """Book one send attempt (self._cond held); return the line when a wait begins."""
        carried = ''
        if ok:
            self.stats.frames_sent += 1
            if self._record:
                self.stats.send_times.append(sent_at)
            if request is not None and not request.done and not request.cancelled:
                assert view is not None  # taken in _run whenever a request was carried
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
        else:
            self.stats.send_failures += 1
            self.stats.last_error = message
            if request is not None and self._request is request and not request.done:
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
                                else 'never sent (' + (self.stats.last_error or 'no slot') + ')')
                        goal = (f'waiting for {TARGETS[request.command].name}'
                                if request.command in TARGETS else 'waiting to be sent')
                        return CommandResult(False, f'{name}: timeout after {timeout:g} s '
                                             f'{goal}, {sent}; {view.describe()}')
                    self._cond.wait(min(POLL_S, deadline - now))
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
