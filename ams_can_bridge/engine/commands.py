# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge's command side without ROS: every device's rows, one pipeline, the armed senders.

``Commands`` is what a bridge (the node, or a test) holds: the rows of every device
instance (``Device.COMMANDS``), each run through the one ``Pipeline`` (engine/calls.py), and
the devices' periodic senders (``Device.attach_senders``), which follow the gate:

- commands enabled: each device's senders are armed once the bus is connected
  (``CommandGate.start_when_connected``: an slcan adapter opens in ~2 s, and a heartbeat
  started before would drop its frames); a call that has just waited for that bus arms
  them at once (``Pipeline`` tells ``fire``);
- commands disabled: a start still waiting for the bus is cancelled, and every sender is
  disarmed before the gate's ``set_enabled(False)`` returns (the gate tells its listeners in
  the caller's thread), so nothing is sent after it;
- a device's start command (``Device.start_command``: the IVT-S's check_config_at_start)
  runs once, through the pipeline, as soon as the device is heard while commands are
  enabled.
"""
from __future__ import annotations

import threading
from functools import partial
from typing import Mapping

from ams_can_bridge.devices.base import Device
from ams_can_bridge.devices.commands import Command
from ams_can_bridge.devices.ports import Armed
from ams_can_bridge.engine.calls import Log, no_config, Pipeline, SetConfig
from ams_can_bridge.engine.gate import CommandGate, PendingStart

START_CHECK_POLL = 0.05  # s between looks for "heard and commands enabled"


class StartCheck:
    """One device's start command: run once when the device is heard while commands are on."""

    def __init__(self, commands: Commands, name: str, row: Command) -> None:
        """Start the thread that waits for the device (it never sends while disabled)."""
        self._commands = commands
        self.name = name
        self.row = row
        self.outcome: tuple[bool, str] | None = None  # (success, answer), once it ran
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f'{name}-check', daemon=True)
        self._thread.start()

    def _run(self) -> None:
        device = self._commands.devices[self.name]
        gate = self._commands.gate
        while not self._stop.wait(START_CHECK_POLL):
            if device.heard() and gate.enabled:
                break
        else:
            return
        self.outcome = self._commands.pipeline.call(
            self.name, device, self.row, source=f'{self.name}/check_config_at_start')

    def stop(self) -> None:
        """End the wait (a check under way finishes first, bounded)."""
        self._stop.set()
        self._thread.join(2.0)


class Commands:
    """Every command row of a bridge through one pipeline; senders armed with the gate."""

    def __init__(self, gate: CommandGate, devices: Mapping[str, Device], log: Log, *,
                 set_config: SetConfig = no_config) -> None:
        """Make each device's senders (armed at once if the gate is), start the checks."""
        self.gate = gate
        self.devices = dict(devices)
        self._log = log
        self.pipeline = Pipeline(gate, log, set_config=set_config, bus_ready=self.fire)
        self.senders: dict[str, list[Armed]] = {}
        for name, device in self.devices.items():
            senders = device.attach_senders(gate.send_periodic, log)
            if senders:
                self.senders[name] = senders
        self._pending: dict[str, PendingStart] = {}
        self._rows = {(name, row.service): row for name, device in self.devices.items()
                      for row in device.COMMANDS}
        gate.add_listener(self.on_commands_enabled)
        if gate.enabled:  # commands_enabled at launch: the bus is not even open yet
            self.on_commands_enabled(True)
        self.start_checks: dict[str, StartCheck] = {}
        for name, device in self.devices.items():
            service = device.start_command()
            if service is not None:
                self.start_checks[name] = StartCheck(self, name, self.row(name, service))

    # --- the rows -------------------------------------------------------------------------
    def rows(self) -> list[tuple[str, Command]]:
        """Return every (instance, row) of the bridge, in device and row order."""
        return [(name, row) for (name, _), row in self._rows.items()]

    def row(self, name: str, service: str) -> Command:
        """Return the row of ``<name>/<service>`` (KeyError: no such command)."""
        return self._rows[(name, service)]

    def call(self, name: str, service: str, data: bool | None = None) -> tuple[bool, str]:
        """Call ``<name>/<service>`` (``data``: a SetBool's request): (success, answer)."""
        return self.pipeline.call(name, self.devices[name], self.row(name, service), data)

    # --- the senders follow the gate ---------------------------------------------------------
    def on_commands_enabled(self, enabled: bool) -> None:
        """Arm every device's senders once the bus is connected; disarm them at once."""
        if not enabled:
            self._disarm(shutdown=False)
            return
        for name, senders in self.senders.items():
            pending = self.gate.start_when_connected(partial(_arm, senders))
            self._pending[name] = pending
            starting = [sender.label for sender in senders if sender.starts_on_arm()]
            if not pending.done and starting:
                verb = 'starts' if len(starting) == 1 else 'start'
                self._log.info(f'{name}: {" and ".join(starting)} {verb} when the CAN bus is '
                               'connected')

    def fire(self, name: str) -> None:
        """Arm the senders of ``name`` now if they wait: a call of it found the bus connected."""
        pending = self._pending.get(name)
        if pending is not None:
            pending.fire()

    def _disarm(self, shutdown: bool) -> None:
        for name, senders in self.senders.items():
            pending = self._pending.pop(name, None)
            if pending is not None:
                pending.cancel()  # after this returns it never starts them
            for sender in senders:
                sender.on_disarm(shutdown)

    def close(self) -> None:
        """Stop every sender and start check; the bridge is shutting down."""
        self.gate.remove_listener(self.on_commands_enabled)
        for check in self.start_checks.values():
            check.stop()
        self._disarm(shutdown=True)


def _arm(senders: list[Armed]) -> None:
    for sender in senders:
        sender.on_arm()
