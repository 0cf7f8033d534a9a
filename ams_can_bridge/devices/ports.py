# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ports a device's command side is given by the layer above (the command gate, a log).

Devices build their frames but never reach the bus themselves: the periodic senders (the AMS
heartbeat, the charger START repeat, the SMA keep-alive) send through a ``SendFrame`` (the
gate's ``send_periodic``), and a command the device runs itself (an IVT-S or EVMS3 exchange,
the charger's start and stop) through a ``CallPort`` the command pipeline hands it
(``engine/commands.py``). Typed here, as Protocols, so that devices import neither the engine nor
ROS.
"""
from __future__ import annotations

from typing import Any, Callable, Iterable, Mapping, Protocol

from ams_can_bridge.protocols.common import Frame


class SendFrame(Protocol):
    """Send one frame now; return (sent, why not)."""

    def __call__(self, frame: Frame, /) -> tuple[bool, str]:
        """Send ``frame``; (False, reason) when the gate or the bus refused it."""


class CallPort(Protocol):
    """
    What the pipeline hands a device for one call it runs itself (``Exchange`` rows).

    Calling it sends one frame of the call (a ``SendFrame``): through the gate, waiting for a
    (re)opening bus, with the command log line, so an exchange's steps pass it one by one.
    """

    def __call__(self, frame: Frame, /) -> tuple[bool, str]:
        """Send one frame of the call; (False, reason) when the gate or the bus refused it."""

    def send_frames(self, build: Callable[[], Iterable[Frame]]) -> tuple[bool, str]:
        """Build and send frames as a ``Frames`` row does: (ok, the pipeline's answer)."""

    def cancelled(self) -> str:
        """Return why a lifecycle transition ended the call ('' while it runs)."""

    def set_config(self, values: Mapping[str, Any]) -> tuple[bool, str]:
        """Set the device's parameters {key: value} all or none: (done, why not)."""


class Armed(Protocol):
    """A periodic sender of a device: it runs only while armed (commands on, bus connected)."""

    label: str  # what it is, in log lines ('the heartbeat')

    def starts_on_arm(self) -> bool:
        """Tell whether arming starts it now (the heartbeat: always; the repeat: never)."""

    def on_arm(self) -> None:
        """Commands are enabled and the bus is connected: run (or allow running)."""

    def on_disarm(self, shutdown: bool = False) -> None:
        """Stop at once; nothing is sent after this returns (shutdown: the bridge ends)."""


class InfoLog(Protocol):
    """The two levels a helper logs at (rclpy's logger or a logging.Logger)."""

    def info(self, message: str) -> object:
        """Log a state change."""

    def warning(self, message: str) -> object:
        """Log a problem the user should see."""


CANCEL_POLL = 0.02  # s: a device waiting for an answer looks at its call's cancel this often


def cancel_reason(send: Any) -> str:
    """
    Return why the call of ``send`` was ended ('' while it runs, or for a plain sender).

    A device waiting for an answer asks this every ``CANCEL_POLL`` s: a lifecycle
    transition ends the calls in flight before it goes on (engine/commands.py).
    """
    cancelled = getattr(send, 'cancelled', None)
    return str(cancelled()) if callable(cancelled) else ''
