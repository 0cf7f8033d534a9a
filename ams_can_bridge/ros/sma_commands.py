"""
SMA device: the inverter keep-alive 0x305 while commands are enabled (no services).

The keep-alive and its frame are the device's (``SmaDevice.attach_keepalive``,
devices/sma_keepalive.py); this module only follows ``commands_enabled``: the keep-alive
runs exactly while commands are enabled and ``<name>.inverter_keepalive`` is true, and stops
at once when either goes false. Its start and stop are logged once each.
"""
from __future__ import annotations

from ams_can_bridge.devices.sma import SmaDevice
from ams_can_bridge.engine.gate import CommandPort, PendingStart
from ams_can_bridge.ros.commander import Commander, ServiceHost


class SmaCommands(Commander[SmaDevice]):
    """The keep-alive of one SMA instance, armed by commands_enabled."""

    def __init__(self, gate: CommandPort, device: SmaDevice, name: str,
                 host: ServiceHost) -> None:
        """Attach the device's keep-alive to the gate (never waiting for the bus); arm it."""
        super().__init__(gate, device, name, host)
        # A keep-alive never waits for the bus: a late one is a wrong one.
        self.keepalive = device.attach_keepalive(gate.send_periodic, host.get_logger().info)
        self._pending: PendingStart | None = None  # the arming, waiting for the bus
        if gate.enabled:  # commands_enabled at launch: the bus is not even open yet
            self.on_commands_enabled(True)

    def on_commands_enabled(self, enabled: bool) -> None:
        """Run the keep-alive (if configured) while commands are enabled and the bus is up."""
        if enabled:
            self._pending = self.gate.start_when_connected(
                lambda: self.keepalive.set_armed(True))
            return
        if self._pending is not None:
            self._pending.cancel()
        self.keepalive.set_armed(False)

    def destroy(self) -> None:
        """Stop the keep-alive."""
        if self._pending is not None:
            self._pending.cancel()
        self.keepalive.stop('the bridge is shutting down')
        self._remove_services()
