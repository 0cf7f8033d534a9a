# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The one periodic sender of the bridge's own frames: heartbeat, charger repeat, keep-alive.

Modelled on python-can's ``ThreadBasedCyclicSendTask`` (can/broadcastmanager.py): a thread
of its own builds each frame just before its slot (python-can's ``modifier_callback``) and
sends it; a hook says what a failed send means (python-can's ``on_error``: go on, or end).
What the bridge needs beyond it:

- slot k is due at ``start + k * period`` on the monotonic clock: sleeping to an absolute
  time cannot drift, and a thread late by a period or more skips the missed slots (counted
  in ``missed_slots``), never sends them in a burst;
- the slots are a fixed grid: a period change takes effect from the next slot on and never
  moves that slot later, and setting the period it has changes nothing (a stream of
  parameter sets must never starve a heartbeat);
- ``stop`` returns only once a frame being sent right now is on the bus and the thread has
  ended, so nothing is sent after it returns; a generation counter makes a thread of an
  earlier start return without sending, whenever it wakes;
- the hooks ``sent(frame, at)`` and ``failed(reason)`` run under the send lock, so a stop and
  a start can never slip a frame between a send and its booking; a line ``sent`` returns is
  logged after that lock (a log call must not hold up a stop).

The frames go to ``send``: the command gate's periodic path, which never waits, neither for
the bus nor for another call's batch (a late heartbeat is a wrong heartbeat).
"""
from __future__ import annotations

import math
import threading
import time
from typing import Callable

from ams_can_bridge import realtime
from ams_can_bridge.devices.ports import SendFrame
from ams_can_bridge.errors import ParamError
from ams_can_bridge.protocols.common import Frame

SentHook = Callable[[Frame, float], str]  # (frame, clock() after the send) -> a line to log
FailedHook = Callable[[str], bool]  # (why not sent) -> go on (True) or end the sender (False)
JOIN_TIMEOUT = 2.0  # s: a stop waits this long at most for the thread to return


class SlotSchedule:
    """Absolute monotonic slots: slot k at start + k * period, late slots skipped."""

    def __init__(self, period: float, start: float) -> None:
        """Start the grid at ``start`` (slot 0) with ``period`` s between slots."""
        if not period > 0:
            raise ParamError(f'period {period!r} must be > 0 s')
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
        """
        Change the period from the next slot on; the same period changes nothing.

        The slots are a fixed grid: a change never moves the next slot later (a stream of
        sets would otherwise starve the frame), only earlier, to one new period after the
        last slot taken when that comes sooner; the slots after it are the new period apart.
        """
        if not period > 0:
            raise ParamError(f'period {period!r} must be > 0 s')
        if period == self.period:
            return
        upcoming = self.due()
        if self.k:  # a slot was taken: a shorter period brings the next one closer
            last = self.start + (self.k - 1) * self.period
            upcoming = min(upcoming, max(last + period, now))
        self.period = period
        self.start = upcoming
        self.k = 0


class PeriodicSender:
    """One frame per slot from a thread of its own, until stopped (see the module docstring)."""

    def __init__(self, name: str, what: str, build: Callable[[], Frame], send: SendFrame,
                 period: float, *, sent: SentHook | None = None,
                 failed: FailedHook | None = None, log: Callable[[str], object] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """
        Make a stopped sender; ``name`` names its thread, ``what`` its frame in messages.

        ``build()`` makes each slot's frame (a raise is a failed slot, the thread goes on);
        ``send(frame) -> (ok, why not)``; without ``failed`` a failed send is counted and
        the sender goes on; ``log`` takes the lines ``sent`` returns.
        """
        if not period > 0:
            raise ParamError(f'{what}: period {period!r} must be > 0 s')
        self.name = name
        self.what = what
        self._build = build
        self._send = send
        self._on_sent = sent
        self._on_failed = failed
        self._log = log
        self._clock = clock
        self._period = float(period)
        self._lock = threading.Lock()  # the thread, the generation, the schedule
        self._send_lock = threading.Lock()  # one send and its booking; stop() waits for it
        # The thread sleeps on an event of its own, not on a lock its owner's calls take:
        # waking into a held lock would make the frame late.
        self._wake = threading.Event()
        self._generation = 0
        self._schedule: SlotSchedule | None = None
        self._thread: threading.Thread | None = None
        self.sent = 0  # frames sent since the last start
        self.failed = 0  # sends that failed since the last start
        self.missed_slots = 0  # slots skipped because the thread was late
        self.last_error = ''

    @property
    def running(self) -> bool:
        """Tell whether the sender's thread is sending."""
        return self._thread is not None

    @property
    def thread(self) -> threading.Thread | None:
        """Return the thread sending now (None while stopped)."""
        return self._thread

    @property
    def period(self) -> float:
        """Return the period in seconds."""
        return self._period

    def start(self, first_slot: int = 0) -> bool:
        """
        Start sending (False: it runs already); slot 0 is now.

        ``first_slot=1``: the first frame one period from now (slot 0 was sent elsewhere).
        """
        with self._lock:
            if self._thread is not None:
                return False
            self._generation += 1
            schedule = SlotSchedule(self._period, self._clock())
            schedule.k = first_slot
            self._schedule = schedule
            self.sent = self.failed = 0
            self._wake.clear()
            self._thread = threading.Thread(target=self._run, args=(self._generation, schedule),
                                            name=self.name, daemon=True)
            self._thread.start()
        return True

    def stop(self) -> bool:
        """Stop at once (True: it was running); nothing is sent after this returns."""
        with self._lock:
            thread, self._thread = self._thread, None
            self._generation += 1  # the thread never sends again, whenever it wakes
        if thread is None:
            return False
        self._wake.set()
        if thread is threading.current_thread():  # from a hook: it returns after the hook
            return True
        with self._send_lock:
            pass  # a frame being sent right now is on the bus before stop() returns
        thread.join(timeout=JOIN_TIMEOUT)
        return True

    def set_period(self, period: float) -> None:
        """
        Change the period at run time, from the next slot on (``SlotSchedule.rebase``).

        The same period changes nothing at all (the thread is not even woken): a slider
        that sets the value it has must not touch the schedule.
        """
        if not period > 0:
            raise ParamError(f'{self.what}: period {period!r} must be > 0 s')
        with self._lock:
            if float(period) == self._period:
                return
            self._period = float(period)
            if self._schedule is not None:
                self._schedule.rebase(self._period, self._clock())
        self._wake.set()

    def _run(self, generation: int, schedule: SlotSchedule) -> None:
        realtime.enter()  # the node's realtime_priority: runs as soon as a slot is due
        while True:
            with self._lock:
                if generation != self._generation:
                    return
                now = self._clock()
                wait = schedule.due() - now
                if wait <= 0:
                    self.missed_slots += schedule.take(now)
            if wait > 0:
                self._wake.wait(wait)
                self._wake.clear()  # a stop or a new period came before set(): look again
                continue
            if not self._slot(generation):
                return

    def _slot(self, generation: int) -> bool:
        """Build and send one slot's frame; False when the thread must end."""
        frame: Frame | None
        try:
            frame, error = self._build(), ''
        except Exception as exc:  # a bad value must not end the thread
            frame, error = None, f'cannot build {self.what}: {exc}'
        line = ''
        with self._send_lock:
            if generation != self._generation:
                return False
            if frame is None:
                ok, message = False, error
            else:
                try:
                    ok, message = self._send(frame)
                except Exception as exc:  # the gate never raises; a bug must not end it
                    ok, message = False, f'{type(exc).__name__}: {exc}'
            at = self._clock()
            if ok:
                assert frame is not None  # sent
                self.sent += 1
                line = self._on_sent(frame, at) if self._on_sent is not None else ''
            else:
                self.failed += 1
                self.last_error = message
                if self._on_failed is not None and not self._on_failed(message):
                    with self._lock:
                        if generation == self._generation:  # ends here, for good
                            self._generation += 1
                            self._thread = None
                    return False
        if line and self._log is not None:
            self._log(line)
        return True
