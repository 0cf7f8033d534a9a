"""
AMS services: car commands in the heartbeat (master role) and the charger-role frames.

The heartbeat and the command/wait rules live in ``devices/ams_master.py`` (no ROS), the
master is the AMS device's own (``AmsDevice.attach_master``) and follows its configuration;
this module offers the services and follows ``commands_enabled``: the heartbeat runs exactly
while commands are enabled. Service callbacks that wait run in the
node's reentrant ``service_group`` and only poll the AMS state, so telemetry (other
callback groups, other executor threads) keeps flowing and ``abort`` can always get in.
"""
from __future__ import annotations

import time
from typing import Any, Callable

from std_srvs.srv import Trigger

from ams_can_bridge.devices.ams_master import CommandResult
from ams_can_bridge.devices.ams import AmsDevice
from ams_can_bridge.errors import RefusedCommand
from ams_can_bridge.protocols.ams import CarCommand, ChargerStart
from ams_can_bridge.protocols.common import EncodeRangeError, Frame
from ams_can_bridge.ros.commander import Commander
from ams_can_bridge.ros.zeva_commands import frame_text, gate_message

CAR_COMMANDS = {
    'enable_sc': (CarCommand.ENABLE_SC, 'enable the safety circuit'),
    'enable_ts': (CarCommand.ENABLE_TS, 'enable the tractive system'),
    'enable_drive': (CarCommand.ENABLE_DRIVE, 'enter drive mode'),
    'abort': (CarCommand.ABORT, 'abort (open TS and SC, back to IDLE)'),
    'set_bank_count': (CarCommand.SET_BANK_COUNT, 'send SET_BANK_COUNT'),
    'sync_time': (CarCommand.SYNC_TIME, 'send SYNC_TIME'),
}


class AmsCommands(Commander):
    """Car-command and charger-role services of one AMS instance."""

    def __init__(self, node: Any, device: AmsDevice, name: str) -> None:
        """Attach the device's (stopped) master to the bus and offer the services."""
        self.node = node
        self.device = device
        self.name = name
        self._t0 = time.monotonic()  # origin of the charger-command time tick
        # The heartbeat never waits for the bus: a late heartbeat is a wrong heartbeat.
        self.master = device.attach_master(lambda frame: node.transmit(frame, wait=False))
        self._services = []
        for suffix, (command, what) in CAR_COMMANDS.items():
            self._service(suffix, self._car_command(command, what))
        self._service('start_charging', self._charger(
            'start charging', lambda: device.charger_frame(ChargerStart.START,
                                                           self.time_tick())))
        self._service('stop_charging', self._charger(
            'stop charging', lambda: device.charger_frame(ChargerStart.STOP, self.time_tick())))
        self._service('set_charge_current', self._charger(
            'set the charge current', device.charge_current_frame))
        self._service('override_bank_count', self._charger(
            'override the bank count', device.bank_count_frame))
        if node.commands_enabled:
            self.master.start()

    # --- hooks for the node ------------------------------------------------------------
    def on_commands_enabled(self, enabled: bool) -> None:
        """Start the heartbeat when commands are enabled, stop it (at once) when not."""
        if enabled:
            self.master.start()
        else:
            self.master.stop('commands_enabled was set to false while waiting; the heartbeat '
                             'stopped')

    def destroy(self) -> None:
        """Stop the heartbeat and remove the services."""
        self.master.stop('the bridge is shutting down')
        for service in self._services:
            self.node.destroy_service(service)
        self._services.clear()

    # --- services ----------------------------------------------------------------------
    def _service(self, suffix: str, callback: Callable) -> None:
        self._services.append(self.node.create_service(
            Trigger, f'{self.name}/{suffix}', callback,
            callback_group=self.node.service_group))

    def _car_command(self, command: CarCommand, what: str) -> Callable:
        def callback(request: Any, response: Any) -> Any:
            # the total bound, waiting for the bus included
            timeout = float(self.device.config.command_timeout or 2.0)
            started = time.monotonic()
            if not self.node.commands_enabled:
                result = CommandResult(False, gate_message(self.node, what))
            else:
                ok, message = self.node.wait_for_bus(limit=timeout)
                if not ok:
                    result = CommandResult(False, f'{command.name} not sent: {message}')
                else:
                    result = self.master.command(command, timeout, started)
            response.success, response.message = result.success, f'{self.name}: {result.message}'
            return response
        return callback

    def _charger(self, what: str, build: Callable[[], Frame]) -> Callable:
        def callback(request: Any, response: Any) -> Any:
            response.success, response.message = self._send_one(what, build)
            return response
        return callback

    def _send_one(self, what: str, build: Callable[[], Frame]) -> tuple[bool, str]:
        if not self.node.commands_enabled:
            return False, f'{self.name}: {gate_message(self.node, what)}'
        try:
            frame = build()
        except (RefusedCommand, EncodeRangeError, ValueError) as exc:
            return False, f'{self.name}: cannot {what}: {exc}; nothing was sent'
        ok, message = self.node.transmit(frame)
        if not ok:
            return False, f'{self.name}: {what} failed: {message}'
        return True, f'{self.name}: {what}: sent {frame_text(frame)}'

    # --- frames --------------------------------------------------------------------------
    def time_tick(self) -> int:
        """Return the charger time tick: ms since this node started, modulo 65536."""
        return int((time.monotonic() - self._t0) * 1000) & 0xFFFF
