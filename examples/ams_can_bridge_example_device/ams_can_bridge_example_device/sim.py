# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The simulated example BMS: a pack discharging at 12 A, which obeys reset-SoC."""
from __future__ import annotations

from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge_example_device import protocol
from ams_can_bridge_example_device.protocol import ExampleCodec, Status

CAPACITY_AH = 50.0
CURRENT_A = -12.0  # discharging


class ExampleSimulator(SimDevice):
    """A pure model: ``tick`` sends the status every 200 ms, ``on_frame`` takes the command."""

    TYPE = 'example_bms'

    def __init__(self, name: str | None = None, base_id: int = protocol.DEFAULT_BASE_ID,
                 soc_pct: float = 80.0) -> None:
        """Start at soc_pct, the status on base_id."""
        super().__init__(name)
        self.codec = ExampleCodec(base_id)
        self.soc_pct = soc_pct
        self.period = Periodic(protocol.STATUS_PERIOD_S)
        self.last: float | None = None

    def tick(self, now: float) -> list[Frame]:
        """Advance the charge; return the status frame when it is due."""
        if self.last is not None:  # coulomb counting: the SoC falls while discharging
            self.soc_pct += CURRENT_A * (now - self.last) / 3600 / CAPACITY_AH * 100
        self.last = now
        if self.faults.silent or not self.period.due(now):
            return []
        soc = max(0, min(100, int(self.soc_pct)))
        frame = self.codec.encode_status(Status(
            voltage_v=44.0 + 0.1 * soc, current_a=CURRENT_A, soc_pct=soc, temperature_c=25,
            fault=self.faults.error_code is not None))
        return [self.corrupt(frame) if self.faults.malformed else frame]

    def on_frame(self, frame: Frame, now: float) -> None:
        """Take the reset-SoC command: the SoC is 100 % from now."""
        if (frame.arbitration_id == self.codec.base_id + protocol.RESET_SOC
                and frame.data == protocol.RESET_SOC_DATA and not frame.is_extended_id):
            self.soc_pct = 100.0
