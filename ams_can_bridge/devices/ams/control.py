# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The AMS's command side without ROS: its command rows, its senders, the frames it sends.

A mixin of ``AmsDevice`` (devices/ams/device.py), as ``IvtSControl`` is of the IVT-S: the rows the
one command pipeline runs (engine/commands.py; devices/commands.py says what a row is), the
master role (heartbeat and car commands, devices/ams/master.py) and the charger role (START
repeat and its ordering rule, devices/ams/charger.py), made by ``attach_senders``, and the
frames built on the device's own codec.
"""
from __future__ import annotations

import time
from typing import Callable, ClassVar

from ams_can_bridge.devices.ams.charger import ChargerRepeater
from ams_can_bridge.devices.ams.master import AmsMaster, AmsView
from ams_can_bridge.devices.base import Sent
from ams_can_bridge.devices.commands import (CARRIED, Carry, Command, EXCHANGE_BUS_FIRST,
                                             ONCE, TRIGGER)
from ams_can_bridge.devices.generated_configs import AmsConfig
from ams_can_bridge.devices.ports import Armed, CallPort, InfoLog, SendFrame
from ams_can_bridge.errors import RefusedCommand
from ams_can_bridge.parameters import ParamSpec
from ams_can_bridge.protocols import ams as proto
from ams_can_bridge.protocols.ams import AmsCodec
from ams_can_bridge.protocols.common import Frame


class AmsControl:
    """Car commands in the heartbeat (master role) and the charger-role frames."""

    name: str
    config: AmsConfig
    codec: AmsCodec
    bank_count: int
    master: AmsMaster | None
    charger: ChargerRepeater | None
    _t0: float
    master_view: Callable[[], AmsView]

    COMMANDS: ClassVar[tuple[Command, ...]] = (
        *(Command(service, what, TRIGGER, 'carry', CARRIED, (command,))
          for service, command, what in (
              ('enable_sc', proto.CarCommand.ENABLE_SC, 'enable the safety circuit'),
              ('enable_ts', proto.CarCommand.ENABLE_TS, 'enable the tractive system'),
              ('enable_drive', proto.CarCommand.ENABLE_DRIVE, 'enter drive mode'),
              ('abort', proto.CarCommand.ABORT, 'abort (open TS and SC, back to IDLE)'),
              ('set_bank_count', proto.CarCommand.SET_BANK_COUNT, 'send SET_BANK_COUNT'),
              ('sync_time', proto.CarCommand.SYNC_TIME, 'send SYNC_TIME'))),
        Command('start_charging', 'start charging', TRIGGER, 'start_charging',
                EXCHANGE_BUS_FIRST),
        Command('stop_charging', 'stop charging', TRIGGER, 'stop_charging',
                EXCHANGE_BUS_FIRST),
        Command('set_charge_current', 'set the charge current', TRIGGER,
                'charge_current_frame', ONCE),
        Command('override_bank_count', 'override the bank count', TRIGGER,
                'bank_count_frame', ONCE),
    )

    COMMAND_PARAMS: ClassVar[list[ParamSpec]] = [
        ParamSpec('heartbeat_period', float, 0.05,
                  's between car-status heartbeats (base + 0x005) while commands_enabled',
                  low=0.01, high=1.0, read_only=False),
        ParamSpec('command_timeout', float, 2.0,
                  's a state command (enable_*, abort) waits for the AMS to report its target '
                  'state', low=0.1, high=60.0, read_only=False),
        ParamSpec('charge_current_a', float, None,
                  'charge current for set_charge_current (base + 0x050), A; no default: '
                  'unset refuses the call', low=0.0, high=25.5, step=0.1, read_only=False),
    ]

    def attach_senders(self, send: SendFrame, log: InfoLog) -> list[Armed]:
        """
        Make this AMS's master (heartbeat, car commands) and charger START repeat, stopped.

        The master follows ``heartbeat_period`` and ``bank_count`` on every configure(); the
        charger time tick counts from now.
        """
        self._t0 = time.monotonic()
        return [self.attach_master(send, log.info), self.attach_charger(send, self.time_tick, log)]

    def attach_master(self, send: SendFrame,
                      log: Callable[[str], object] | None = None) -> AmsMaster:
        """Make this AMS's master (stopped) sending through ``send``; ``log`` hears it."""
        config = self.config
        self.master = AmsMaster(self.heartbeat_frame, send, self.master_view,
                                period=float(config.heartbeat_period or 0.05),
                                bank_count=self.bank_count, log=log, name=self.name)
        return self.master

    def attach_charger(self, send: SendFrame,
                       tick: Callable[[], int], logger: InfoLog) -> ChargerRepeater:
        """Make this AMS's charger START repeater (disarmed) sending through ``send``."""
        self.charger = ChargerRepeater(self.charger_frame, send, tick, logger, self.name)
        return self.charger

    def time_tick(self) -> int:
        """Return the charger time tick: ms since the senders were made, modulo 65536."""
        return int((time.monotonic() - self._t0) * 1000) & 0xFFFF

    def carry(self, command: proto.CarCommand) -> Carry:
        """Return a car command for the heartbeat, bounded by ``command_timeout``."""
        assert self.master is not None, 'attach_senders makes the master'
        return Carry(self.master, command, command.name,
                     float(self.config.command_timeout or 2.0))

    def start_charging(self, port: CallPort) -> tuple[bool, str]:
        """Send START once, then repeat it (the charger's ordering rule: ams_charger.py)."""
        return self._charger().start_charging(port)

    def stop_charging(self, port: CallPort) -> tuple[bool, str]:
        """End the START repeat, then send STOP once: no START ever follows it."""
        return self._charger().stop_charging(port)

    def _charger(self) -> ChargerRepeater:
        assert self.charger is not None, 'attach_senders makes the charger'
        return self.charger

    def heartbeat_frame(self, command: int, bank_count: int, counter: int) -> Frame:
        """Build the car status (base + 0x005) the AMS master sends as its heartbeat."""
        return self.codec.encode(proto.CarStatus(proto.CarCommand(command), bank_count, counter))

    def sent_ids(self, config: AmsConfig | None = None) -> dict[tuple[int, bool], Sent]:
        """Return the heartbeat, the charger command (repeated) and the two overrides."""
        return {(self.codec.id_of(offset), False): sent for offset, sent in (
            (proto.CAR_STATUS, Sent('car status heartbeat', True)),
            (proto.CHARGER_COMMANDS, Sent('charger START/STOP', True)),
            (proto.OVERRIDE_CHARGE_CURRENT, Sent('set_charge_current')),
            (proto.OVERRIDE_BANK_COUNT, Sent('override_bank_count')))}

    def charger_frame(self, start: proto.ChargerStart, time_tick: int) -> Frame:
        """Build a charger command (base + 0x010): start / stop at this time tick."""
        return self.codec.encode(proto.ChargerCommand(start, time_tick))

    def charge_current_frame(self) -> Frame:
        """Build the charge current override (base + 0x050); RefusedCommand while unset."""
        current_a = self.config.charge_current_a
        if current_a is None:
            raise RefusedCommand(f'{self.name}.charge_current_a is not set: set it to the '
                                 'charge current in A (0..25.5 in steps of 0.1)')
        return self.codec.encode(proto.OverrideChargeCurrent(float(current_a)))

    def bank_count_frame(self) -> Frame:
        """Build the bank count override (base + 0x051) with the configured bank count."""
        return self.codec.encode(proto.OverrideBankCount(self.bank_count))
