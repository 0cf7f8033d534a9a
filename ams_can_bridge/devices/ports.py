"""
The ports a device's command helpers are given by the layer above (the command gate, a log).

Devices build their frames but never reach the bus themselves: the AMS master, the charger
START repeat, the SMA keep-alive, the EVMS3 read-back and the IVT-S exchange send through a
``SendFrame`` the ROS adapter hands them (the gate's ``send``/``send_periodic``). Typed here,
as Protocols, so that devices import neither the engine nor ROS.
"""
from __future__ import annotations

from typing import Protocol

from ams_can_bridge.protocols.common import Frame


class SendFrame(Protocol):
    """Send one frame now; return (sent, why not)."""

    def __call__(self, frame: Frame, /) -> tuple[bool, str]:
        """Send ``frame``; (False, reason) when the gate or the bus refused it."""


class InfoLog(Protocol):
    """The two levels a helper logs at (rclpy's logger or a logging.Logger)."""

    def info(self, message: str) -> object:
        """Log a state change."""

    def warning(self, message: str) -> object:
        """Log a problem the user should see."""
