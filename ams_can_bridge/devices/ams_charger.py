"""
The charger role's periodic START (base + 0x010) without ROS: doc/protocols.md section 1.

The seed gives the charger commands "Transmission Rate: Periodically: 100 ms": a charger
keeps its request alive by repeating it. So once ``start_charging`` has put its first START
on the bus, :class:`ChargerRepeater` repeats START, each with the current time tick, every
``CHARGER_COMMAND_PERIOD`` from its own thread on an absolute schedule (the heartbeat's
``HeartbeatSchedule``: no drift, late slots skipped, never a burst). It stops at once, and
for good (a later ``start_charging`` begins anew), when:

- ``stop_charging`` is called (the node then sends STOP once: :meth:`halt`);
- commands are disabled (:meth:`disarm`; nothing at all is sent while disarmed, so no STOP);
- a repeat cannot be sent (bus down): the request is dropped, never replayed when the bus
  returns, exactly as a heartbeat command is.

``halt``/``disarm`` return only after a repeat being sent right now is on the bus, so no START
ever follows them. Start and stop are logged once each, never per frame.
"""
from __future__ import annotations

import threading
import time
from typing import Callable

from ams_can_bridge.devices.ams_master import HeartbeatSchedule
from ams_can_bridge.protocols.ams import ChargerStart
from ams_can_bridge.devices.ports import InfoLog, SendFrame
from ams_can_bridge.protocols.common import Frame

CHARGER_COMMAND_PERIOD = 0.1  # s, seed 003 "Charger commands ... Periodically: 100ms"


class ChargerRepeater:
    """Repeats the charger START every 100 ms while a charging request is active and armed."""

    def __init__(self, build: Callable[[ChargerStart, int], Frame],
                 send: SendFrame, tick: Callable[[], int],
                 logger: InfoLog, name: str = 'ams', period: float = CHARGER_COMMAND_PERIOD,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """
        Wire the repeater: build(start, tick) makes the 0x010 frame, send(frame) -> (ok, msg).

        logger has info() and warning() (rclpy's logger, or logging's).
        """
        self._build = build
        self._send = send
        self._tick = tick
        self._log = logger
        self._name = name
        self.period = float(period)
        self._clock = clock
        self._cond = threading.Condition()
        self._send_lock = threading.Lock()  # halt() returns only after an in-flight send
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._generation = 0
        self._active = False
        self.armed = False
        self.frames_sent = 0  # repeats of this request (the first START is the caller's)
        self.last_stop = ''   # why the last request ended ('' = never ended)

    @property
    def active(self) -> bool:
        """Tell whether START is being repeated now."""
        return self._active

    def arm(self) -> None:
        """Allow requests (commands_enabled became true); nothing is resumed."""
        with self._cond:
            self.armed = True

    def disarm(self, reason: str) -> bool:
        """Refuse requests and stop the repeat at once, sending nothing; True if it ran."""
        with self._cond:
            self.armed = False
        return self.halt(reason)

    def begin(self) -> str:
        """
        Start repeating START one period after the caller's first one; '' or why not.

        Called right after the caller sent that first START; refused while disarmed (a
        disarm between that send and this call wins: the START is not repeated).
        """
        with self._cond:
            if not self.armed:
                return 'commands_enabled is false: START is not repeated'
            if self._active:
                return ''
            self._active = True
            self._generation += 1
            self.frames_sent = 0
            schedule = HeartbeatSchedule(self.period, self._clock())
            schedule.k = 1  # slot 0 was the caller's START
            self._thread = threading.Thread(target=self._run, args=(self._generation, schedule),
                                            name=f'{self._name}-charger-start', daemon=True)
            self._thread.start()
        self._log.info(f'{self._name}: charger START (0x010) repeated every '
                       f'{self.period * 1000:g} ms until stop_charging or commands_enabled '
                       'false')
        return ''

    def halt(self, reason: str) -> bool:
        """Stop repeating at once (no frame sent here); True if it was running."""
        with self._cond:
            was_active = self._active
            self._active = False
            thread, self._thread = self._thread, None
            if was_active:
                self.last_stop = reason
            self._cond.notify_all()
        self._wake.set()
        with self._send_lock:
            pass  # a repeat being sent right now is on the bus before halt() returns
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2.0)
        if was_active:
            self._log.info(f'{self._name}: charger START no longer repeated ({reason}); '
                           f'{self.frames_sent} repeats sent')
        return was_active

    def _alive(self, generation: int) -> bool:
        return self._active and self._generation == generation

    def _run(self, generation: int, schedule: HeartbeatSchedule) -> None:
        while True:
            with self._cond:
                if not self._alive(generation):
                    return
                now = self._clock()
                wait = schedule.due() - now
                if wait <= 0:
                    schedule.take(now)  # late slots are skipped, never sent in a burst
            if wait > 0:
                self._wake.wait(wait)
                self._wake.clear()
                continue
            with self._send_lock:
                if not self._alive(generation):
                    return
                try:
                    ok, message = self._send(self._build(ChargerStart.START, self._tick()))
                except Exception as exc:  # a bug must not leave a request half alive
                    ok, message = False, f'cannot build the charger command: {exc}'
                if ok:
                    self.frames_sent += 1
                    continue
                with self._cond:
                    self._active = False
                    self._thread = None
                    self.last_stop = f'a repeat was not sent: {message}'
            self._log.warning(f'{self._name}: charger START no longer repeated: a repeat was '
                              f'not sent ({message}); the request is dropped and will not be '
                              'sent later: call start_charging again')
            return
