# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA BMS16 in its standard form (``<name>.variant: standard``): EVMS3 protocol, 29-bit IDs.

doc/protocols.md section 6. The status frame (ID 30, byte 5 = 255) gives state, error,
remaining Ah, pack voltage and temperature; the cells come as BMS12 modules 0 and 1 (8 + up to
8), the current (when the BMS16 has a shunt) on ID 40. SoC = remaining Ah /
``config.pack_capacity_ah``, NaN while that is unset, as for the EVMS3. A status frame at the
same ID without the marker (an EVMS3) is malformed here: never published as a BMS16's data,
and write_config is refused until a BMS16 has been heard, so a BMS16 configuration (full
voltage in 1 V steps, cells in slot 6, shunt size in slot 7) never reaches an EVMS3.
"""
from __future__ import annotations

import time
from typing import Any, Callable, Iterable, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, Device, DiagnosticReport, Level, NAN, PowerSupplyStatus, Sent)
from ams_can_bridge.devices.commands import Command, Frames, ONCE, TRIGGER
from ams_can_bridge.devices.config import ConfigFields
from ams_can_bridge.devices.generated_configs import Bms16StdConfig
from ams_can_bridge.devices.evms3.health import error_health, error_text
from ams_can_bridge.devices.timed import TimedSpans, TimedStore
from ams_can_bridge.errors import RefusedCommand
from ams_can_bridge.parameters import config_param_specs
from ams_can_bridge.protocols import bms16_std as proto
from ams_can_bridge.protocols.bms16_std import (
    Bms16StdCodec, Bms16StdStatus, CELLS_PER_MODULE, CONFIG_GAP_S,
    DEFAULT_BASE_ID, MAX_CELLS)
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import (
    AcknowledgeError, BatteryCurrent, Bms12Cells, CONFIG1, EVMS3_WARNINGS, Evms3Error,
    Evms3State, PowerOff, ResetSoc)

VARIANT = 'standard'


class Bms16StdDevice(Device[Bms16StdConfig]):
    """One ZEVA BMS16 speaking the EVMS3 protocol (the BMS16v2 standard form)."""

    TYPE = 'bms16'
    Config = Bms16StdConfig
    codec: Bms16StdCodec
    VARIANT = VARIANT
    ID_BITS = 29
    BROADCAST_PERIOD = 0.25  # the Monitor times out its core after 4 ticks of 4 Hz
    DEFAULT_BASE_ID = DEFAULT_BASE_ID
    PARAMS = []
    COMMAND_PARAMS = config_param_specs(proto.CONFIG_FIELDS)
    CONFIG = ConfigFields(proto.CONFIG_FIELDS, proto.check_config_value)
    WRITE_HINT = 'set them all: the BMS16 has no read-back, a write overwrites every value'
    # write_config: IDs 36, 32..35 with this pause after each frame (ZEVA Monitor: 20 ms)
    CONFIG_FRAME_GAP = CONFIG_GAP_S
    COMMANDS = (
        Command('write_config', 'write the configuration', TRIGGER, 'config_frames',
                Frames(paced=True, say_gap=True)),
        Command('acknowledge_error', 'acknowledge the error', TRIGGER, 'ack_frame', ONCE),
        Command('reset_soc', 'reset the SoC', TRIGGER, 'reset_soc_frame', ONCE),
        Command('power_off', 'power the BMS16 off', TRIGGER, 'power_off_frame', ONCE),
    )

    def __init__(self, name: str, config: Bms16StdConfig | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, config, clock)
        base_id = self.config.base_id
        self.codec = Bms16StdCodec(DEFAULT_BASE_ID if base_id is None else int(base_id))
        self.status: Bms16StdStatus | None = None
        self.status_stamp = NAN
        self._cells = TimedSpans.uniform(4, MAX_CELLS // 4)  # one span per BMS12 frame
        self._current: TimedStore[type, float] = TimedStore()  # wire sign: + = discharge

    def config_problems(self, config: Bms16StdConfig,
                        keys: Iterable[str] | None = None) -> list[str]:
        """Name every config.* value the BMS16 (standard form) refuses."""
        return self.CONFIG.problems(self.name, config, keys)

    @property
    def error(self) -> Evms3Error | None:
        """Return the error the BMS16 reports now (None before its first status frame)."""
        status = self.status
        return None if status is None else status.error

    # --- the frames the command services send -----------------------------------------------
    def _require_bms16(self, what: str) -> None:
        if self.is_stale():
            raise RefusedCommand(
                f'no BMS16 status (ID {self.codec.base_id} with byte 5 = 255) within '
                f'stale_timeout, so {what}: a status without that marker is another device '
                '(an EVMS3 uses the same IDs with other meanings)')

    def config_frames(self) -> list[Frame]:
        """Build IDs 36, 32..35 (the Monitor's order) from the configuration now."""
        self._require_bms16('nothing is written')
        config = self.config
        optional = (('balance_v',) if config.config_balance_mode in ('dynamic', 'off')
                    else ())
        values = self.CONFIG.complete(self.name, config, optional, self.WRITE_HINT)
        return self.codec.config_frames(proto.config_from_mapping(values))

    def sent_ids(self, config: Bms16StdConfig | None = None) -> dict[tuple[int, bool], Sent]:
        """Return IDs 32..39 (configuration, acknowledge, SoC reset, power off)."""
        base, extended = self.codec.base_id, self.codec.is_extended_id
        whats = ['write_config'] * 5 + ['acknowledge_error', 'reset_soc', 'power_off']
        return {(base + offset, extended): Sent(what)
                for offset, what in enumerate(whats, start=CONFIG1)}

    def ack_frame(self) -> Frame:
        """Build ID 37 with the error reported now; RefusedCommand if stale or no error."""
        self._require_bms16('its error is unknown')
        error = self.error
        if error is None or error == Evms3Error.NONE:
            raise RefusedCommand('the BMS16 reports no error to acknowledge')
        return self.codec.encode(AcknowledgeError(error))

    def reset_soc_frame(self) -> Frame:
        """Build ID 38 (reset SoC to 100 %, no data)."""
        return self.codec.encode(ResetSoc())

    def power_off_frame(self) -> Frame:
        """Build ID 39 (power off, no data)."""
        return self.codec.encode(PowerOff())

    # --- bus thread --------------------------------------------------------------------------
    def _handle(self, reading: Any, stamp: float) -> bool:
        if isinstance(reading, Bms12Cells):
            first = CELLS_PER_MODULE * reading.module + reading.first_cell
            self._cells.put(first // 4, reading.voltages_v, self.clock())
            return False
        if isinstance(reading, Bms16StdStatus):
            self.status = reading
            self.status_stamp = stamp
            return True
        if isinstance(reading, BatteryCurrent):
            self._current.put(BatteryCurrent, reading.current_a, self.clock())
        return False

    # --- helpers (lock held) ---------------------------------------------------------------
    def cell_count(self) -> int:
        """Cells from config.cells, 16 while that is unset."""
        cells = self.config.config_cells
        return MAX_CELLS if cells is None else max(1, min(MAX_CELLS, int(cells)))

    def _fresh_cells(self) -> list[float]:
        return self._cells.read(self.clock(), self.stale_timeout)[:self.cell_count()]

    def _capacity_ah(self) -> float:
        capacity = self.config.config_pack_capacity_ah
        return NAN if capacity is None else float(capacity)

    def _ros_current(self) -> float:
        current_a = self._current.get(BatteryCurrent, self.clock(), self.stale_timeout)
        if current_a is None:
            return NAN
        return -current_a if current_a else 0.0

    # --- reports: what the engine publishes --------------------------------------------------
    def _battery_report(self) -> BatteryReport:
        current = self._ros_current()
        capacity = self._capacity_ah()
        report = BatteryReport(current=current, capacity=capacity, design_capacity=capacity,
                               cell_voltage=self._fresh_cells())
        status = self.status
        if status is None:
            return report
        report.stamp = self.status_stamp
        report.voltage = status.pack_voltage_v
        report.charge = status.amp_hours_ah
        if capacity == capacity:
            report.percentage = min(1.0, max(0.0, status.amp_hours_ah / capacity))
        report.temperature = NAN if status.temperature_c is None else float(status.temperature_c)
        report.power_supply_status = (PowerSupplyStatus.CHARGING
                                      if status.state == Evms3State.CHARGING
                                      else current_status(current))
        report.power_supply_health = error_health(status.error)
        report.present = True
        return report

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        status = self.status
        values: dict[str, str] = {'variant': 'standard (EVMS3 protocol, 29-bit IDs)'}
        if status is None:
            return DiagnosticReport(Level.OK, f'no BMS16 status frame (ID {self.codec.base_id}'
                                    ' with byte 5 = 255) yet', values)
        level = (Level.OK if status.error == Evms3Error.NONE else
                 Level.WARN if status.error in EVMS3_WARNINGS else Level.ERROR)
        message = f'{status.state.name}, {error_text(status.error)}'
        if with_values:
            self._values(status, values)
        return DiagnosticReport(level, message, values)

    def _values(self, status: Bms16StdStatus, values: dict[str, str]) -> None:
        capacity = self._capacity_ah()
        current = self._ros_current()
        values.update({
            'state': status.state.name,
            'error': error_text(status.error),
            'error code': str(int(status.error)),
            'amp hours remaining (Ah)': f'{status.amp_hours_ah:.1f}',
            'state of charge (%)': ('unknown: config.pack_capacity_ah unset'
                                    if capacity != capacity
                                    else f'{100 * status.amp_hours_ah / capacity:.1f}'),
            'pack voltage (V)': f'{status.pack_voltage_v:.1f}',
            'temperature (degC)': ('no sensor' if status.temperature_c is None
                                   else str(status.temperature_c)),
            'current (A, discharge negative)': ('not received (ID 40)' if current != current
                                                else f'{current:.3f}'),
        })
        cells = self._fresh_cells()
        for k, volts in enumerate(cells):
            values[f'cell {k + 1} V'] = f'{volts:g}'
        known = [v for v in cells if v == v]
        if known:
            values['cell min V'] = f'{min(known):g}'
            values['cell max V'] = f'{max(known):g}'
