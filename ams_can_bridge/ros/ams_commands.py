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
from ams_can_bridge.engine.gate import CommandPort, PendingStart
from ams_can_bridge.errors import EncodeRangeError, RefusedCommand
from ams_can_bridge.protocols.ams import CarCommand, ChargerStart
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.ros.commander import Commander, ServiceHost
from ams_can_bridge.ros.zeva_commands import frame_text

CAR_COMMANDS = {
    'enable_sc': (CarCommand.ENABLE_SC, 'enable the safety circuit'),
    'enable_ts': (CarCommand.ENABLE_TS, 'enable the tractive system'),
    'enable_drive': (CarCommand.ENABLE_DRIVE, 'enter drive mode'),
    'abort': (CarCommand.ABORT, 'abort (open TS and SC, back to IDLE)'),
    'set_bank_count': (CarCommand.SET_BANK_COUNT, 'send SET_BANK_COUNT'),
    'sync_time': (CarCommand.SYNC_TIME, 'send SYNC_TIME'),
}


class AmsCommands(Commander[AmsDevice]):
    """Car-command and charger-role services of one AMS instance."""

    def __init__(self, gate: CommandPort, device: AmsDevice, name: str,
                 host: ServiceHost) -> None:
        """Attach the device's (stopped) master to the gate and offer the services."""
        super().__init__(gate, device, name, host)
        self._t0 = time.monotonic()  # origin of the charger-command time tick
        # The heartbeat never waits for the bus (nor for another call's frames): a late
        # heartbeat is a wrong heartbeat. The gate's periodic path does neither.
        self.master = device.attach_master(gate.send_periodic, host.get_logger().info)
        # The repeats never wait either: one that cannot go out ends the request.
        self.charger = device.attach_charger(gate.send_periodic, self.time_tick,
                                             host.get_logger())
        self._charging_lock = threading.Lock()  # start/stop_charging one at a time
        for suffix, (command, what) in CAR_COMMANDS.items():
            self._service(Trigger, suffix, self._car_command(command, what))
        self._service(Trigger, 'start_charging', self._start_charging)
        self._service(Trigger, 'stop_charging', self._stop_charging)
        self._service(Trigger, 'set_charge_current', self._charger(
            'set the charge current', device.charge_current_frame))
        self._service(Trigger, 'override_bank_count', self._charger(
            'override the bank count', device.bank_count_frame))
        self._heartbeat_logged = False  # the last heartbeat state logged
        self._pending: PendingStart | None = None  # the heartbeat's start, waiting for the bus
        if gate.enabled:  # commands_enabled at launch: the bus is not even open yet
            self.on_commands_enabled(True)

    # --- hooks for the gate and the node -----------------------------------------------
    def on_commands_enabled(self, enabled: bool) -> None:
        """Start the heartbeat once the bus is connected; stop it and the charger repeat."""
        if enabled:
            self.charger.arm()  # a charging request ended by the disarm is not resumed
            self._pending = self.gate.start_when_connected(self._start_heartbeat)
            if not self._pending.done:
                self.host.get_logger().info(f'{self.name}: the heartbeat starts when the CAN '
                                            'bus is connected')
            return
        if self._pending is not None:
            self._pending.cancel()
        self.charger.disarm('commands_enabled was set to false; no STOP sent')
        self.master.stop('commands_enabled was set to false while waiting; the heartbeat '
                         'stopped')
        self._log_heartbeat('commands_enabled is false')

    def _start_heartbeat(self) -> None:
        self.master.start()
        self._log_heartbeat()

    def _log_heartbeat(self, why: str = '') -> None:
        """Log the heartbeat starting or stopping (once per change, never per frame)."""
        running = bool(self.master.running)
        if running == self._heartbeat_logged:
            return
        self._heartbeat_logged = running
        if running:
            base = getattr(self.device.config, 'base_id', None)
            frame = f' 0x{base + 5:X}' if isinstance(base, int) else ''
            self.host.get_logger().info(
                f'{self.name}: heartbeat started: car status{frame} every '
                f'{self.master.period * 1000:g} ms')
        else:
            because = f' ({why})' if why else ''
            self.host.get_logger().info(f'{self.name}: heartbeat stopped{because}')

    def destroy(self) -> None:
        """Stop the heartbeat, the charger repeat, and remove the services."""
        if self._pending is not None:
            self._pending.cancel()
        self.charger.disarm('the bridge is shutting down')
        self.master.stop('the bridge is shutting down')
        if self.host.context.ok():  # after Ctrl-C the logger may be gone with the context
            self._log_heartbeat('the bridge is shutting down')
        self._remove_services()

    # --- services ----------------------------------------------------------------------

    def _car_command(self, command: CarCommand, what: str) -> Callable:
        def callback(request: Any, response: Any) -> Any:
            # the total bound, waiting for the bus included
            timeout = float(self.device.config.command_timeout or 2.0)
            started = time.monotonic()
            if not self.gate.enabled:
                result = CommandResult(False, self.gate.refusal(what))
            else:
                ok, message = self.gate.wait_for_bus(limit=timeout)
                if not ok:
                    result = CommandResult(False, f'{command.name} not sent: {message}')
                else:
                    if self._pending is not None:  # the bus has just connected: start it
                        self._pending.fire()  # now, not when its waiting thread wakes
                    result = self.master.command(command, timeout, started)
            response.success, response.message = result.success, f'{self.name}: {result.message}'
            return response
        return callback

    def _start_charging(self, request: Any, response: Any) -> Any:
        with self._charging_lock:
            if self.gate.enabled and self.charger.active:
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
            repeated = self.gate.enabled and self.charger.halt('stop_charging')
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
        if not self.gate.enabled:
            return False, f'{self.name}: {self.gate.refusal(what)}'
        try:
            frame = build()
        except (RefusedCommand, EncodeRangeError) as exc:  # anything else is a bug
            return False, f'{self.name}: cannot {what}: {exc}; nothing was sent'
        ok, message = self.gate.transmit(frame)
        if not ok:
            return False, f'{self.name}: {what} failed: {message}'
        return True, f'{self.name}: {what}: sent {frame_text(frame)}'

    # --- frames --------------------------------------------------------------------------
    def time_tick(self) -> int:
        """Return the charger time tick: ms since this node started, modulo 65536."""
        return int((time.monotonic() - self._t0) * 1000) & 0xFFFF
