# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The example BMS's state: its status frame -> BatteryState and diagnostics, one command."""
from __future__ import annotations

import dataclasses
import time
from typing import Any, Callable, ClassVar, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, Device, DiagnosticReport, Level, NAN, PowerSupplyHealth, Sent)
from ams_can_bridge.devices.commands import Command, ONCE, TRIGGER
from ams_can_bridge.devices.config import DeviceConfig
from ams_can_bridge.parameters import ParamSpec
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge_example_device import protocol
from ams_can_bridge_example_device.protocol import ExampleCodec, Status


@dataclasses.dataclass(frozen=True)
class ExampleConfig(DeviceConfig):
    """An instance's parameters (the common ones, base_id, capacity_ah), typed."""

    KEYS: ClassVar[tuple[str, ...]] = (
        'frame_id', 'location', 'serial_number', 'stale_timeout', 'base_id', 'capacity_ah')

    stale_timeout: float = 5 * protocol.STATUS_PERIOD_S
    base_id: int = protocol.DEFAULT_BASE_ID
    capacity_ah: float | None = None


class ExampleDevice(Device[ExampleConfig]):
    """One example BMS."""

    TYPE = 'example_bms'
    Config = ExampleConfig
    codec: ExampleCodec
    BROADCAST_PERIOD = protocol.STATUS_PERIOD_S
    DEFAULT_BASE_ID = protocol.DEFAULT_BASE_ID
    PARAMS = [ParamSpec('capacity_ah', float, None, 'rated capacity of the pack in Ah',
                        low=0.0, high=10000.0)]
    # one service, <name>/reset_soc (std_srvs/Trigger): the frame reset_soc_frame builds,
    # sent once through the bridge's command gate (refused while commands_enabled is false)
    COMMANDS = (Command('reset_soc', 'reset the SoC', TRIGGER, 'reset_soc_frame', ONCE),)

    def __init__(self, name: str, config: ExampleConfig | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Check the parameters, build the codec on base_id."""
        super().__init__(name, config, clock)
        self.codec = ExampleCodec(self.config.base_id)
        self.status: Status | None = None
        self.status_stamp = NAN

    def sent_ids(self, config: ExampleConfig | None = None) -> dict[tuple[int, bool], Sent]:
        """Return the command's ID (the bridge checks no other instance uses it)."""
        base = (config or self.config).base_id
        return {(base + protocol.RESET_SOC, False): Sent('reset_soc')}

    def reset_soc_frame(self) -> Frame:
        """Build the reset-SoC frame (the reset_soc service)."""
        return self.codec.reset_soc()

    def _handle(self, reading: Any, stamp: float) -> bool:
        self.status = reading
        self.status_stamp = stamp
        return True  # the status is the primary frame: it keeps the device fresh

    def _battery_report(self) -> BatteryReport:
        report = BatteryReport()
        if self.config.capacity_ah is not None:
            report.capacity = report.design_capacity = self.config.capacity_ah
        status = self.status
        if status is None:
            return report
        report.stamp = self.status_stamp
        report.voltage = status.voltage_v
        report.current = status.current_a
        report.temperature = float(status.temperature_c)
        report.percentage = status.soc_pct / 100
        report.power_supply_status = current_status(report.current)
        report.power_supply_health = (PowerSupplyHealth.UNSPEC_FAILURE if status.fault
                                      else PowerSupplyHealth.GOOD)
        report.present = True
        return report

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        status = self.status
        if status is None:
            return DiagnosticReport(Level.OK, 'no status frame yet')
        values = {'soc %': str(status.soc_pct), 'voltage V': f'{status.voltage_v:g}',
                  'current A': f'{status.current_a:g}',
                  'temperature degC': str(status.temperature_c), 'fault': str(status.fault)}
        return DiagnosticReport(Level.ERROR if status.fault else Level.OK,
                                'fault' if status.fault else f'OK, SoC {status.soc_pct} %',
                                values if with_values else {})
