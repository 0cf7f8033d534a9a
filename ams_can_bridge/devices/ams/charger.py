# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The charger role's START/STOP (base + 0x010) without ROS: doc/protocols.md section 1.

The seed gives the charger commands "Transmission Rate: Periodically: 100 ms": a charger
keeps its request alive by repeating it. So once ``start_charging`` has put its first START
on the bus, :class:`ChargerRepeater` repeats START, each with the current time tick, every
``CHARGER_COMMAND_PERIOD`` (one ``PeriodicSender``: its own thread, an absolute schedule, no
drift, late slots skipped, never a burst). It stops at once, and for good (a later
``start_charging`` begins anew), when:

- ``stop_charging`` is called (the repeat ends first, then STOP is sent once);
- commands are disabled (:meth:`disarm`; nothing at all is sent while disarmed, so no STOP);
- a repeat cannot be sent (bus down): the request is dropped, never replayed when the bus
  returns, exactly as a heartbeat command is.

The ordering rule lives here: ``start_charging`` and ``stop_charging`` run one at a time, and
the repeat has ended (its thread joined) before the STOP is sent, so no START ever follows a
STOP. Both send their one frame through the command pipeline's port (``CallPort``), which
refuses while disabled, waits for the bus and words the answer. Start and stop of the repeat
are logged once each, never per frame.
"""
from __future__ import annotations

import threading
import time
from typing import Callable

from ams_can_bridge.devices.sender_thread import PeriodicSender
from ams_can_bridge.devices.ports import CallPort, InfoLog, SendFrame
from ams_can_bridge.protocols.ams import ChargerStart
from ams_can_bridge.protocols.common import Frame

CHARGER_COMMAND_PERIOD = 0.1  # s, seed 003 "Charger commands ... Periodically: 100ms"


class ChargerRepeater:
    """Repeats the charger START every 100 ms while a charging request is active and armed."""

    label = 'the charger START repeat'  # an armed sender (``devices/ports.py``: ``Armed``)

    def __init__(self, build: Callable[[ChargerStart, int], Frame],
                 send: SendFrame, tick: Callable[[], int],
                 logger: InfoLog, name: str = 'ams', period: float = CHARGER_COMMAND_PERIOD,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """
        Wire the repeater: build(start, tick) makes the 0x010 frame, send(frame) -> (ok, msg).

        logger has info() and warning() (rclpy's logger, or logging's).
        """
        self._build = build
        self._tick = tick
        self._log = logger
        self._name = name
        self._lock = threading.Lock()  # armed, and a begin against a disarm
        self._calls = threading.Lock()  # start_charging / stop_charging one at a time
        self._sender = PeriodicSender(f'{name}-charger-start', 'the charger command',
                                      lambda: build(ChargerStart.START, tick()), send, period,
                                      failed=self._failed, clock=clock)
        self.armed = False
        self.last_stop = ''   # why the last request ended ('' = never ended)

    @property
    def active(self) -> bool:
        """Tell whether START is being repeated now."""
        return self._sender.running

    @property
    def period(self) -> float:
        """Return the repeat period in seconds."""
        return self._sender.period

    @property
    def frames_sent(self) -> int:
        """Return the repeats of this request (the first START is the caller's)."""
        return self._sender.sent

    @property
    def thread(self) -> threading.Thread | None:
        """Return the repeat's sender, a thread; None while not repeating."""
        return self._sender.thread

    # --- the two services: the ordering rule ------------------------------------------------
    def start_charging(self, port: CallPort) -> tuple[bool, str]:
        """Send START once through ``port``, then repeat it until stop_charging or a disarm."""
        with self._calls:
            if self.active:
                return True, (f'{self._name}: start charging: START is already repeated every '
                              f'{self.period * 1000:g} ms; nothing more sent')
            ok, message = port.send_frames(lambda: [self._build(ChargerStart.START,
                                                                self._tick())])
            if not ok:
                return False, message
            refused = self.begin()
            if refused:
                return False, f'{message}; not repeated: {refused}'
            return True, (f'{message}, repeated every {self.period * 1000:g} ms until '
                          'stop_charging or commands_enabled false')

    def stop_charging(self, port: CallPort) -> tuple[bool, str]:
        """End the repeat (its thread joined), then send STOP once: no START follows it."""
        with self._calls:
            repeated = self.halt('stop_charging')
            ok, message = port.send_frames(lambda: [self._build(ChargerStart.STOP,
                                                                self._tick())])
            if repeated:
                message += '; the repeated START has ended'
            return ok, message

    # --- an armed sender ----------------------------------------------------------------------
    def starts_on_arm(self) -> bool:
        """Tell that arming starts nothing: only start_charging does."""
        return False

    def on_arm(self) -> None:
        """Commands are enabled and the bus is connected: allow requests."""
        self.arm()

    def on_disarm(self, shutdown: bool = False) -> None:
        """Stop the repeat at once and refuse requests, sending nothing (no STOP)."""
        self.disarm('the bridge is shutting down' if shutdown else
                    'commands_enabled was set to false; no STOP sent')

    def arm(self) -> None:
        """Allow requests; nothing is resumed."""
        with self._lock:
            self.armed = True

    def disarm(self, reason: str) -> bool:
        """Refuse requests and stop the repeat at once, sending nothing; True if it ran."""
        with self._lock:
            self.armed = False
        return self.halt(reason)

    # --- the repeat ---------------------------------------------------------------------------
    def begin(self) -> str:
        """
        Start repeating START one period after the caller's first one; '' or why not.

        Called right after the caller sent that first START; refused while disarmed (a
        disarm between that send and this call wins: the START is not repeated).
        """
        with self._lock:
            if not self.armed:
                return 'commands_enabled is false: START is not repeated'
            if not self._sender.start(first_slot=1):  # slot 0 was the caller's START
                return ''  # repeats already
        self._log.info(f'{self._name}: charger START (0x010) repeated every '
                       f'{self.period * 1000:g} ms until stop_charging or commands_enabled '
                       'false')
        return ''

    def halt(self, reason: str) -> bool:
        """Stop repeating at once (no frame sent here); True if it was running."""
        if not self._sender.stop():  # returns once a repeat being sent is on the bus
            return False
        self.last_stop = reason
        self._log.info(f'{self._name}: charger START no longer repeated ({reason}); '
                       f'{self.frames_sent} repeats sent')
        return True

    def _failed(self, message: str) -> bool:
        """End the request for good: a repeat was not sent (send lock held)."""
        self.last_stop = f'a repeat was not sent: {message}'
        self._log.warning(f'{self._name}: charger START no longer repeated: a repeat was '
                          f'not sent ({message}); the request is dropped and will not be '
                          'sent later: call start_charging again')
        return False
