"""
SMA device: the inverter keep-alive 0x305 while commands are enabled (no services).

The keep-alive and its frame are the device's (``SmaDevice.attach_keepalive``,
devices/sma_keepalive.py); this module only follows ``commands_enabled``: the keep-alive
runs exactly while commands are enabled and ``<name>.inverter_keepalive`` is true, and stops
at once when either goes false. Its start and stop are logged once each.
"""
from __future__ import annotations

from typing import Any

from ams_can_bridge.devices.sma import SmaDevice
from ams_can_bridge.ros.commander import Commander


class SmaCommands(Commander):
    """The keep-alive of one SMA instance, armed by commands_enabled."""

    def __init__(self, node: Any, device: SmaDevice, name: str) -> None:
        """Attach the device's keep-alive to the bus (never waiting for it) and arm it."""
        self.node = node
        self.name = name
        logger = node.get_logger()
        # A keep-alive never waits for the bus: a late one is a wrong one.
        self.keepalive = device.attach_keepalive(
            lambda frame: node.transmit(frame, wait=False), logger.info)
        self.keepalive.set_armed(node.commands_enabled)

    def on_commands_enabled(self, enabled: bool) -> None:
        """Run the keep-alive (if configured) while commands are enabled, stop it at once not."""
        self.keepalive.set_armed(enabled)

    def destroy(self) -> None:
        """Stop the keep-alive."""
        self.keepalive.stop('the bridge is shutting down')
