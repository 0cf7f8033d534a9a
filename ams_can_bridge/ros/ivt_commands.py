"""
IVT-S services: read_config, write_config, set_running, restart, reset_errors (0x411 -> 0x511).

The device builds every command and waits for each answer (devices/ivt_s.py,
devices/ivt_s_commands.py); this module only offers the services, applies the transmit gate
and, with ``<name>.check_config_at_start``, reads the configuration once the sensor is heard
while commands are enabled. Nothing is sent unless ``commands_enabled`` is true; a refused
call sends nothing.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

from std_srvs.srv import SetBool, Trigger

from ams_can_bridge.devices.ivt_s import IvtSDevice
from ams_can_bridge.engine.gate import CommandPort
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.ros.commander import Commander, ServiceHost

START_CHECK_POLL = 0.05  # s between looks for "heard and commands enabled"


class IvtCommands(Commander[IvtSDevice]):
    """The command services of one IVT-S instance."""

    def __init__(self, gate: CommandPort, device: IvtSDevice, name: str,
                 host: ServiceHost) -> None:
        """Offer the services; start the one-time check when check_config_at_start is set."""
        super().__init__(gate, device, name, host)
        self._stop = threading.Event()
        self.start_check: tuple[bool, str] | None = None  # its outcome, once done
        for suffix, what, call in (
                ('read_config', 'read the configuration', device.read_config),
                ('write_config', 'write the configuration', device.write_config),
                ('restart', 'restart the sensor', device.restart),
                ('reset_errors', 'reset the errors', device.reset_errors)):
            self._service(Trigger, suffix, self._trigger(what, call))
        self._service(SetBool, 'set_running', self._set_running)
        self._thread: threading.Thread | None = None
        if device.config.check_config_at_start:
            self._thread = threading.Thread(target=self._check_at_start,
                                            name=f'{name}-check', daemon=True)
            self._thread.start()

    # --- hooks for the node ------------------------------------------------------------
    def destroy(self) -> None:
        """Stop the start check and remove the services."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self._remove_services()

    # --- services ----------------------------------------------------------------------
    def _send(self, frame: Frame) -> tuple[bool, str]:
        return self.gate.transmit(frame)  # the gate again at each frame; waits for the bus

    def _call(self, what: str, call: Callable[[Callable], tuple[bool, str]]) -> tuple[bool, str]:
        if not self.gate.enabled:
            return False, f'{self.name}: {self.gate.refusal(what)}'
        return call(self._send)

    def _trigger(self, what: str, call: Callable) -> Callable:
        def callback(request: Any, response: Any) -> Any:
            response.success, response.message = self._call(what, call)
            return response
        return callback

    def _set_running(self, request: Any, response: Any) -> Any:
        running = bool(request.data)
        response.success, response.message = self._call(
            'run the sensor' if running else 'stop the sensor',
            lambda send: self.device.set_running(send, running))
        return response

    # --- check_config_at_start -----------------------------------------------------------
    def _check_at_start(self) -> None:
        """Wait until the sensor is heard while commands are enabled; read once."""
        while not self._stop.wait(START_CHECK_POLL):
            if self.device.heard() and self.gate.enabled:
                break
        else:
            return
        ok, message = self.device.read_config(self._send)
        self.start_check = (ok, message)
        log = self.host.get_logger()
        (log.info if ok else log.error)(f'check_config_at_start: {message}')
