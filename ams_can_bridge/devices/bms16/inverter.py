# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA BMS16 state: status + cell frames (and its SMA frames) -> BatteryState, diagnostics.

The BMS16 sends its own frames from ``base_id`` (status, cells) and the SMA Sunny Island
frames 0x351.. at fixed IDs; this device takes both. Its wire current is positive while
discharging: the report negates it (ROS: negative while discharging).
The number of cells comes from the ``bms16.config.cells`` parameter (declared with the
configuration values by the command layer), 16 while that is unset.
Every group of data expires on its own after ``stale_timeout``: each cell frame (6 cells) and
each SMA frame, so cells whose frame stopped show NaN while the status frame keeps coming.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Iterable, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, Device, DiagnosticReport, Level, NAN, PowerSupplyHealth, Sent)
from ams_can_bridge.devices.commands import Command, ONCE, TRIGGER
from ams_can_bridge.devices.config import ConfigFields
from ams_can_bridge.devices.generated_configs import Bms16Config
from ams_can_bridge.devices.sma.device import sma_values
from ams_can_bridge.devices.timed import TimedSpans, TimedStore
from ams_can_bridge.errors import MalformedFrameError, ParamError
from ams_can_bridge.parameters import config_param_specs
from ams_can_bridge.protocols import bms16 as bms16_proto
from ams_can_bridge.protocols.bms16 import (
    BMS16_WARNINGS, Bms16Cells, Bms16Codec, Bms16Error, Bms16Settings, Bms16Status,
    CELL_FRAME_COUNT, CELL_FRAME_FIRST, CELLS_3, DEFAULT_BASE_ID, MAX_CELLS)
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.sma import (
    SMA_IDS, SmaAlarms, SmaBattery, SmaBatteryInfo, SmaCodec, SmaLimits, SmaManufacturer,
    SmaSoc)

HEALTH = {
    Bms16Error.NONE: PowerSupplyHealth.GOOD,
    Bms16Error.LOAD_DISABLED_UNDERVOLTAGE: PowerSupplyHealth.DEAD,
    Bms16Error.CRITICAL_VOLTAGE: PowerSupplyHealth.DEAD,
    Bms16Error.CHARGE_DISABLED_OVERVOLTAGE: PowerSupplyHealth.OVERVOLTAGE,
    Bms16Error.OVERTEMPERATURE: PowerSupplyHealth.OVERHEAT,
}


class Bms16FrameCodec:
    """The frames a BMS16 sends: its status/cell frames (base..base+3) and the SMA ones."""

    is_extended_id = False

    def __init__(self, base_id: int, instance: str = 'bms16') -> None:
        self.bms16 = Bms16Codec(base_id)
        self.sma = SmaCodec()
        own = frozenset(range(base_id + 0, base_id + CELLS_3 + 1))
        if own & SMA_IDS:
            raise ParamError(f'{instance}.base_id = {base_id} overlaps the SMA IDs 0x351..0x35F '
                             '(the BMS16 sends base_id .. base_id + 3 and the SMA frames)')
        self._own = own
        self.arbitration_ids = own | SMA_IDS

    def decode(self, arbitration_id: int, data: bytes) -> Any:
        """Decode a status / cell frame or an SMA frame."""
        if arbitration_id in self._own:
            return self.bms16.decode(arbitration_id, data)
        if arbitration_id in SMA_IDS:
            return self.sma.decode(arbitration_id, data)
        raise MalformedFrameError(arbitration_id, data, 'not a BMS16 ID')


class Bms16Device(Device[Bms16Config]):
    """One ZEVA BMS16."""

    TYPE = 'bms16'
    Config = Bms16Config
    codec: Bms16FrameCodec
    BROADCAST_PERIOD = 0.25
    DEFAULT_BASE_ID = DEFAULT_BASE_ID
    PARAMS = []

    COMMAND_PARAMS = config_param_specs(bms16_proto.CONFIG_FIELDS)
    COMMANDS = (
        Command('write_config', 'write the configuration', TRIGGER, 'config_frames', ONCE),
        Command('acknowledge_error', 'acknowledge the error', TRIGGER, 'ack_frame', ONCE),
        Command('reset_soc', 'reset the SoC', TRIGGER, 'reset_soc_frame', ONCE),
        Command('power_off', 'power the BMS16 off', TRIGGER, 'power_off_frame', ONCE),
    )
    CONFIG = ConfigFields(bms16_proto.CONFIG_FIELDS, bms16_proto.check_config_value)
    WRITE_HINT = 'set them all: the device has no read-back, a write overwrites every value'

    def __init__(self, name: str, config: Bms16Config | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, config, clock)
        base_id = self.config.base_id
        self.codec = Bms16FrameCodec(DEFAULT_BASE_ID if base_id is None else int(base_id), name)
        self.status: Bms16Status | None = None
        self.status_stamp = NAN
        self._cells = TimedSpans(CELL_FRAME_COUNT)  # one span per cell frame
        self._sma: TimedStore[type, Any] = TimedStore()  # by message type: any of them

    @property
    def error(self) -> Bms16Error:
        """Return the error code last reported (NONE until the first status frame)."""
        status = self.status
        return Bms16Error.NONE if status is None else status.error

    def config_problems(self, config: Bms16Config,
                        keys: Iterable[str] | None = None) -> list[str]:
        """Name every config.* value the BMS16 protocol refuses."""
        return self.CONFIG.problems(self.name, config, keys)

    # --- the frames the command services send (built here, on the device's own codec) --------
    def config_frames(self) -> list[Frame]:
        """Build frames base + 4, base + 5 from the configuration now (all values set)."""
        values = self.CONFIG.complete(self.name, self.config, (), self.WRITE_HINT)
        return self.codec.bms16.config_frames(Bms16Settings(**values))

    def sent_ids(self, config: Bms16Config | None = None) -> dict[tuple[int, bool], Sent]:
        """Return base + 4 .. base + 8 (configuration, acknowledge, SoC reset, power off)."""
        p, base = bms16_proto, self.codec.bms16.base_id
        return {(base + offset, False): Sent(what) for offset, what in (
            (p.CONFIG_1, 'write_config'), (p.CONFIG_2, 'write_config'),
            (p.ACK_ERROR, 'acknowledge_error'), (p.RESET_SOC, 'reset_soc'),
            (p.POWER_OFF, 'power_off'))}

    def ack_frame(self) -> Frame:
        """Build frame base + 6 (acknowledge error)."""
        return self.codec.bms16.encode(bms16_proto.AcknowledgeError())

    def reset_soc_frame(self) -> Frame:
        """Build frame base + 7 (reset SoC to 100 %)."""
        return self.codec.bms16.encode(bms16_proto.ResetSoc())

    def power_off_frame(self) -> Frame:
        """Build frame base + 8 (power off)."""
        return self.codec.bms16.encode(bms16_proto.PowerOff())

    def cell_count(self) -> int:
        """Cells from the bms16.config.cells parameter, 16 while that is unset."""
        cells = self.config.config_cells
        if cells is None:
            return MAX_CELLS
        return max(1, min(MAX_CELLS, int(cells)))

    def _handle(self, reading: Any, stamp: float) -> bool:
        if isinstance(reading, Bms16Status):
            self.status = reading
            self.status_stamp = stamp
            return True
        if isinstance(reading, Bms16Cells):
            self._cells.put(CELL_FRAME_FIRST.index(reading.first_cell), reading.voltages_v,
                            self.clock())
            return False
        if isinstance(reading, (SmaLimits, SmaSoc, SmaBattery, SmaAlarms, SmaManufacturer,
                                SmaBatteryInfo)):
            self._sma.put(type(reading), reading, self.clock())
        return False

    def _fresh_cells(self) -> list[float]:
        """Return the cell voltages (lock held), NaN where their frame is older than stale."""
        return self._cells.read(self.clock(), self.stale_timeout)

    def _fresh_sma(self) -> dict[type, Any]:
        """Return the SMA readings (lock held) whose frame came within stale_timeout."""
        return self._sma.fresh(self.clock(), self.stale_timeout)

    def _battery_report(self) -> BatteryReport:
        report = BatteryReport(cell_voltage=self._fresh_cells()[:self.cell_count()])
        capacity = self.config.config_pack_capacity_ah
        if capacity is not None:
            report.capacity = report.design_capacity = float(capacity)
        status = self.status
        if status is None:
            return report
        report.stamp = self.status_stamp
        report.voltage = status.voltage_v
        report.current = -status.current_a if status.current_a else 0.0
        report.temperature = float(status.temperature_c)
        report.percentage = status.soc_pct / 100
        if not math.isnan(report.capacity):
            report.charge = report.capacity * report.percentage
        report.power_supply_status = current_status(report.current)
        report.power_supply_health = HEALTH.get(status.error, PowerSupplyHealth.UNSPEC_FAILURE)
        report.present = True
        return report

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        status = self.status
        values: dict[str, str] = {}
        level = Level.OK
        parts: list[str] = []
        if status is None:
            parts.append('no status frame yet')
        else:
            error = status.error
            if error != Bms16Error.NONE:
                level = Level.WARN if error in BMS16_WARNINGS else Level.ERROR
                parts.append(('warning ' if level == Level.WARN else 'error ') + error.name)
            else:
                parts.append('OK')
            parts.append(f'SoC {status.soc_pct} %, {status.voltage_v:.1f} V, '
                         f'{-status.current_a if status.current_a else 0.0:.1f} A')
            values.update({
                'error': error.name, 'error code': str(int(error)),
                'soc %': str(status.soc_pct), 'voltage V': f'{status.voltage_v:g}',
                'current A (wire, positive = discharge)': f'{status.current_a:g}',
                'temperature degC': str(status.temperature_c),
            })
        sma = self._fresh_sma()
        if with_values:
            count = self.cell_count()
            cells = self._fresh_cells()
            for k in range(count):
                values[f'cell {k + 1} V'] = f'{cells[k]:g}'
            known = [v for v in cells[:count] if not math.isnan(v)]
            if known:
                values['cell min V'] = f'{min(known):g}'
                values['cell max V'] = f'{max(known):g}'
            values.update(sma_values(sma, prefix='sma '))
        alarms = sma.get(SmaAlarms)
        if alarms is not None:
            # The SMA flags mirror the BMS16's state: an active one is never downgraded.
            if alarms.active_alarms:
                level = max(level, Level.ERROR)
                parts.append('SMA alarms ' + ', '.join(alarms.active_alarms))
            if alarms.active_warnings:
                level = max(level, Level.WARN)
                parts.append('SMA warnings ' + ', '.join(alarms.active_warnings))
        return DiagnosticReport(level, '; '.join(parts), values)
