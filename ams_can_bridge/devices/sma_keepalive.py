"""
The inverter keep-alive an SMA-protocol BMS may wait for (doc/protocols.md section 5).

Pylontech's CAN protocol has the inverter answer every second with 0x305, eight zero bytes;
Pylontech-family BMSs (and BMSs copying them) may stop or alarm without it. A robot has no
inverter, so the bridge can play its part: ``sma.inverter_keepalive``.

The keep-alive runs exactly while it is both *armed* (commands_enabled, set by the ROS
layer) and *enabled* (the device's ``inverter_keepalive`` parameter): either going false
stops it at once, and no frame is sent after ``stop`` returns. It sends its first frame
when it starts, then one per period on an absolute schedule (no drift; a late thread skips
missed slots rather than sending a burst). Start and stop are logged once each, never a
line per frame; failed sends are counted for the diagnostics.
"""
from __future__ import annotations

import threading
import time
from typing import Callable

from ams_can_bridge.devices.ports import SendFrame
from ams_can_bridge.protocols.common import Frame

KEEPALIVE_PERIOD = 1.0  # s: "Inverter reply every second" (Pylontech CAN protocol)


class InverterKeepalive:
    """0x305 every period while armed and enabled; the frame comes from the device."""

    def __init__(self, build: Callable[[], Frame], send: SendFrame,
                 log: Callable[[str], None], name: str = 'sma',
                 period: float = KEEPALIVE_PERIOD) -> None:
        """build() makes the frame, send(frame) -> (ok, message), log(line) reports."""
        self._build = build
        self._send = send
        self._log = log
        self.name = name
        self.period = float(period)
        self._lock = threading.Lock()  # state changes
        self._send_lock = threading.Lock()  # stop() returns only after an in-flight send
        self._wake = threading.Event()
        self._armed = False
        self._enabled = False
        self._generation = 0
        self._thread: threading.Thread | None = None
        self.sent = 0
        self.failed = 0
        self.last_error = ''

    @property
    def running(self) -> bool:
        """Tell whether frames are being sent."""
        return self._thread is not None

    def set_armed(self, armed: bool, reason: str = '') -> None:
        """Follow commands_enabled."""
        self._update(armed=bool(armed), reason=reason or 'commands_enabled is false')

    def set_enabled(self, enabled: bool) -> None:
        """Follow the inverter_keepalive parameter."""
        self._update(enabled=bool(enabled), reason=f'{self.name}.inverter_keepalive is false')

    def stop(self, reason: str) -> None:
        """Stop for good reason (shutdown): disarm."""
        self._update(armed=False, reason=reason)

    def _update(self, armed: bool | None = None, enabled: bool | None = None,
                reason: str = '') -> None:
        with self._lock:
            if armed is not None:
                self._armed = armed
            if enabled is not None:
                self._enabled = enabled
            want = self._armed and self._enabled
            thread = self._thread
            if want and thread is None:
                self._generation += 1
                self._wake.clear()
                self._thread = threading.Thread(
                    target=self._run, args=(self._generation,), daemon=True,
                    name=f'{self.name}-keepalive')
                self._thread.start()
                self._log(f'{self.name}: inverter keep-alive started: 0x305 every '
                          f'{self.period:g} s')
                return
            if want or thread is None:
                return
            self._generation += 1  # the old thread never sends again
            self._thread = None
        self._wake.set()
        with self._send_lock:
            pass  # a frame being sent right now is on the bus before this returns
        if thread is not threading.current_thread():
            thread.join(timeout=2.0)
        self._log(f'{self.name}: inverter keep-alive stopped ({reason}); '
                  f'{self.sent} frames sent, {self.failed} failed')

    def _alive(self, generation: int) -> bool:
        return self._generation == generation

    def _run(self, generation: int) -> None:
        due = time.monotonic()
        while True:
            wait = due - time.monotonic()
            if wait > 0:
                self._wake.wait(wait)
            with self._send_lock:
                if not self._alive(generation):
                    return
                now = time.monotonic()
                if now < due:
                    continue  # woken early, still armed: sleep on
                try:
                    ok, message = self._send(self._build())
                except Exception as exc:  # a failing send must not end the thread
                    ok, message = False, str(exc)
                if ok:
                    self.sent += 1
                else:
                    self.failed += 1
                    self.last_error = message
            # next slot on the grid; after a stall skip the missed ones, never a burst
            due += self.period * max(1, int((now - due) // self.period) + 1)

    def describe(self) -> str:
        """One diagnostics value: what the keep-alive is doing."""
        if not self.running:
            if not self._enabled:
                return 'off'
            return 'off: commands_enabled is false'
        text = f'sending 0x305 every {self.period:g} s ({self.sent} sent'
        if self.failed:
            text += f', {self.failed} failed, last: {self.last_error}'
        return text + ')'
