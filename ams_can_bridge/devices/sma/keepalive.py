# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The inverter keep-alive an SMA-protocol BMS may wait for (doc/protocols.md section 5).

Pylontech's CAN protocol has the inverter answer every second with 0x305, eight zero bytes;
Pylontech-family BMSs (and BMSs copying them) may stop or alarm without it. A robot has no
inverter, so the bridge can play its part: ``sma.inverter_keepalive``.

The keep-alive runs exactly while it is both *armed* (commands enabled and the bus connected:
the command side arms it) and *enabled* (the device's ``inverter_keepalive`` parameter):
either going false stops it at once, and no frame is sent after that returns. It is one
``PeriodicSender``: its first frame when it starts, then one per period on an absolute
schedule (no drift; a late thread skips missed slots rather than sending a burst). Start and
stop are logged once each, never a line per frame; failed sends are counted for the
diagnostics.
"""
from __future__ import annotations

import threading
from typing import Callable

from ams_can_bridge.devices.sender_thread import PeriodicSender
from ams_can_bridge.devices.ports import SendFrame
from ams_can_bridge.protocols.common import Frame

KEEPALIVE_PERIOD = 1.0  # s: "Inverter reply every second" (Pylontech CAN protocol)


class InverterKeepalive:
    """0x305 every period while armed and enabled; the frame comes from the device."""

    label = 'the inverter keep-alive'  # an armed sender (``devices/ports.py``: ``Armed``)

    def __init__(self, build: Callable[[], Frame], send: SendFrame,
                 log: Callable[[str], object], name: str = 'sma',
                 period: float = KEEPALIVE_PERIOD) -> None:
        """build() makes the frame, send(frame) -> (ok, message), log(line) reports."""
        self._log = log
        self.name = name
        self._lock = threading.Lock()  # armed / enabled and the start or stop they make
        self._sender = PeriodicSender(f'{name}-keepalive', 'the keep-alive', build, send,
                                      period)
        self._armed = False
        self._enabled = False

    @property
    def running(self) -> bool:
        """Tell whether frames are being sent."""
        return self._sender.running

    @property
    def thread(self) -> threading.Thread | None:
        """Return the keep-alive's sender, a thread; None while stopped."""
        return self._sender.thread

    @property
    def period(self) -> float:
        """Return the period in seconds."""
        return self._sender.period

    @property
    def sent(self) -> int:
        """Return the frames sent since it last started."""
        return self._sender.sent

    @property
    def failed(self) -> int:
        """Return the sends that failed since it last started."""
        return self._sender.failed

    @property
    def last_error(self) -> str:
        """Return why the last send failed ('' = none yet)."""
        return self._sender.last_error

    # --- an armed sender ----------------------------------------------------------------------
    def starts_on_arm(self) -> bool:
        """Tell whether arming starts it (inverter_keepalive is true)."""
        return self._enabled

    def on_arm(self) -> None:
        """Run (if inverter_keepalive is true): commands are enabled, the bus is connected."""
        self.set_armed(True)

    def on_disarm(self, shutdown: bool = False) -> None:
        """Stop at once, saying why."""
        self.set_armed(False, 'the bridge is shutting down' if shutdown else '')

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
            if self._armed and self._enabled:
                if self._sender.start():
                    self._log(f'{self.name}: inverter keep-alive started: 0x305 every '
                              f'{self.period:g} s')
            elif self._sender.stop():  # returns once a frame being sent is on the bus
                self._log(f'{self.name}: inverter keep-alive stopped ({reason}); '
                          f'{self.sent} frames sent, {self.failed} failed')

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
