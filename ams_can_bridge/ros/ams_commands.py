"""
AMS services: car commands in the heartbeat (master role) and the charger-role frames.

The heartbeat and the command/wait rules live in ``devices/ams_master.py`` (no ROS), the
master is the AMS device's own (``AmsDevice.attach_master``) and follows its configuration;
this module offers the services and follows ``commands_enabled``: the heartbeat runs exactly
while commands are enabled. ``start_charging`` sends START and has the device's
``ChargerRepeater`` (``devices/ams_charger.py``) repeat it every 100 ms until
``stop_charging`` (STOP sent once) or commands are disabled (nothing sent); the two calls
are serialised, so a STOP is never followed by a START. Service callbacks that wait run in the
node's reentrant ``service_group`` and only poll the AMS state, so telemetry (other
callback groups, other executor threads) keeps flowing and ``abort`` can always get in.
"""
from __future__ import annotations

import threading
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
        # The repeats never wait for the bus either: one that cannot go out ends the request.
        self.charger = device.attach_charger(lambda frame: node.transmit(frame, wait=False),
                                             self.time_tick, node.get_logger())
        self._charging_lock = threading.Lock()  # start/stop_charging one at a time
        self._services = []
        for suffix, (command, what) in CAR_COMMANDS.items():
            self._service(suffix, self._car_command(command, what))
        self._service('start_charging', self._start_charging)
        self._service('stop_charging', self._stop_charging)
        self._service('set_charge_current', self._charger(
            'set the charge current', device.charge_current_frame))
        self._service('override_bank_count', self._charger(
            'override the bank count', device.bank_count_frame))
        if node.commands_enabled:
            self.master.start()
            self.charger.arm()

    # --- hooks for the node ------------------------------------------------------------
    def on_commands_enabled(self, enabled: bool) -> None:
        """Start the heartbeat when commands are enabled; stop it and the charger repeat."""
        if enabled:
            self.master.start()
            self.charger.arm()  # a charging request ended by the disarm is not resumed
        else:
            self.charger.disarm('commands_enabled was set to false; no STOP sent')
            self.master.stop('commands_enabled was set to false while waiting; the heartbeat '
                             'stopped')

    def destroy(self) -> None:
        """Stop the heartbeat, the charger repeat, and remove the services."""
        self.charger.disarm('the bridge is shutting down')
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

    def _start_charging(self, request: Any, response: Any) -> Any:
        with self._charging_lock:
            if self.node.commands_enabled and self.charger.active:
                response.success = True
                response.message = (f'{self.name}: start charging: START is already repeated '
                                    f'every {self.charger.period * 1000:g} ms; nothing more '
                                    'sent')
                return response
            ok, message = self._send_one('start charging', lambda: self.device.charger_frame(
                ChargerStart.START, self.time_tick()))
            if ok:
                refused = self.charger.begin()
                message += (f'; not repeated: {refused}' if refused else
                            f', repeated every {self.charger.period * 1000:g} ms until '
                            'stop_charging or commands_enabled false')
                ok = not refused
        response.success, response.message = ok, message
        return response

    def _stop_charging(self, request: Any, response: Any) -> Any:
        with self._charging_lock:
            # the repeat ends first: no START can follow the STOP on the bus
            repeated = (self.node.commands_enabled
                        and self.charger.halt('stop_charging'))
            ok, message = self._send_one('stop charging', lambda: self.device.charger_frame(
                ChargerStart.STOP, self.time_tick()))
            if repeated:
                message += '; the repeated START has ended'
        response.success, response.message = ok, message
        return response

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
