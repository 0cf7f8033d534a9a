# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA EVMS3 state: status (ID 30), battery current (ID 40), BMS12 modules and TC chargers.

What the EVMS commands is shown too: the balance target it sends each BMS12 module (300 + 10 m,
mV, 0 = off) and, per TC charger 1..3, its command (target volts / amps, "shutdown by BMS")
and the charger's answer (output volts / amps, status bits: any set bit is WARN). Each of
these expires on its own (NaN / left out after its timeout), like the module cells.

The EVMS3 does not send its state of charge: SoC = remaining Ah / ``config.pack_capacity_ah``
(a configuration value the commanding part declares), NaN while that is unset. The current
on the wire is positive while discharging; BatteryState wants the opposite sign.

Rules from ZEVA's open EVMS3 firmware and Monitor (doc/protocols.md section 3): in stationary
mode warning 4 (low cell) opens the main contactor and warning 6 (high cell) disables
charging; a configuration is written only while the EVMS reports IDLE or SETUP, cell counts
(ID 36) first, because the EVMS saves to EEPROM only when ID 35 arrives; an ID 30 with byte
5 = 255 comes from a BMS16 in its standard form, which must not get an EVMS3 write.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Iterable, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, DiagnosticReport, Device, Level, PowerSupplyStatus, Sent)
from ams_can_bridge.devices.config import ConfigFields
from ams_can_bridge.devices.generated_configs import Evms3Config
from ams_can_bridge.devices.evms3.health import (
    error_health, error_text, WRITABLE_STATES)
from ams_can_bridge.devices.evms3.peers import Bms12Module, Chargers
from ams_can_bridge.devices.evms3.readback import ConfigReader, read_back, ReadResult
from ams_can_bridge.devices.commands import (Command, EXCHANGE, Frames, ONCE, SET_BOOL,
                                             TRIGGER)
from ams_can_bridge.devices.ports import CallPort, SendFrame
from ams_can_bridge.devices.timed import TimedStore
from ams_can_bridge.parameters import config_param_specs, ParamSpec
from ams_can_bridge.protocols import evms3 as evms3_proto
from ams_can_bridge.errors import ParamError, RefusedCommand
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import (
    AcknowledgeError, BatteryCurrent, BMS12_MAX_MODULES, Bms12Cells, Bms12Request,
    Bms12Temperatures, BmsCellNumbers, ConfigReport, Evms3Codec, Evms3Settings, Evms3Error,
    Evms3State, Evms3Status, EVMS3_WARNINGS, READBACK_IDS, RequestConfig, ResetSoc, SetState)
from ams_can_bridge.protocols.evms3_config import check_config_value
from ams_can_bridge.protocols.tc_charger import ChargerCommand, ChargerStatus

NAN = math.nan
CELLS_PER_BMS12 = 12  # t = 1..3 carry 3 x 4 cells: a module cannot report more
# The EVMS polls each BMS12 at least once a second (else the module stops balancing):
# three missed polls make a module's cells unknown, whatever the status stale_timeout is.
BMS12_STALE_TIMEOUT = 3.0
# TC chargers and the EVMS's commands to them come about once a second: five missed.
CHARGER_STALE_TIMEOUT = 5.0


# doc/protocols.md 3.6: 32..36 change the EVMS3's RAM at once; only 35 saves to EEPROM.
EVMS3_PARTIAL = ('the EVMS3 saves its configuration to EEPROM only when ID 35 arrives, so the '
                 'frames sent changed its RAM only: it runs with them until its next power-up, '
                 'which restores the saved configuration; call write_config again (all five '
                 'frames) once commands are enabled')


class Evms3Device(Device[Evms3Config]):
    """ZEVA EVMS3 (+ BMS12 modules): BatteryState from ID 30/40 and the module cells."""

    TYPE = 'evms3'
    Config = Evms3Config
    codec: Evms3Codec
    ID_BITS = 29
    EXTENDED_ID_CHOICE = True  # ZEVA's firmware can be built with 11-bit IDs
    DEFAULT_EXTENDED_ID = True
    EXTENDED_ID_HELP = ('29-bit IDs for the EVMS3 and BMS12 frames (false: a firmware built '
                        'with 11-bit IDs); the TC chargers always use 29-bit IDs')
    BROADCAST_PERIOD = 0.25
    DEFAULT_BASE_ID = 30
    PARAMS = [
        ParamSpec('bms12_modules', int, 0,
                  'how many BMS12 modules (IDs 300 + 10 m) to expect, 0..16; cells per '
                  'module: 12, or config.cells_per_module when set', low=0, high=16, step=1),
        ParamSpec('voltage_multiplier', int, 1,
                  "the EVMS3 build's PACK_VOLTAGE_MULTIPLIER: 1 (up to ~400 V) or 2 (800 V "
                  'builds: full and charge voltages count 2x per step)', low=1, high=2, step=1),
    ]

    COMMAND_PARAMS = config_param_specs(evms3_proto.CONFIG_FIELDS) + [
        ParamSpec('config_request', bool, False,
                  'allow read_config to send ID 51: ZEVA motor controllers use ID 51 for '
                  'their throttle frame, so leave false on a bus with one', read_only=False),
        ParamSpec('read_timeout', float, 2.0,
                  's read_config waits for the answer (IDs 52..56) after sending ID 51',
                  low=0.1, high=30.0, read_only=False),
    ]

    # write_config: IDs 36, 32..35 with this pause after each frame, as ZEVA's Monitor sends
    # them (EVMS_Monitor3.c TransmitSettings: CanTX(..., 20)); the EVMS3 saves on ID 35
    CONFIG_FRAME_GAP = 0.02
    COMMANDS = (
        Command('write_config', 'write the configuration', TRIGGER, 'config_frames',
                Frames(paced=True, partial=EVMS3_PARTIAL)),
        Command('set_setup_mode', 'enter Setup mode', SET_BOOL, 'setup_mode_frame', ONCE,
                what_false='return to Idle'),
        Command('acknowledge_error', 'acknowledge the error', TRIGGER, 'ack_frame', ONCE),
        Command('reset_soc', 'reset the SoC', TRIGGER, 'reset_soc_frame', ONCE),
        Command('read_config', 'read the configuration', TRIGGER, 'read_back', EXCHANGE),
    )

    CONFIG = ConfigFields(evms3_proto.CONFIG_FIELDS, evms3_proto.check_config_value)
    WRITE_HINT = ('set them all, or fill them from the EVMS3 with {0}/read_config: a write '
                  'overwrites every value')

    def __init__(self, name: str, config: Evms3Config | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, config, clock)
        config = self.config
        self.base_id = self.DEFAULT_BASE_ID if config.base_id is None else int(config.base_id)
        modules = int(config.bms12_modules or 0)
        if not 0 <= modules <= BMS12_MAX_MODULES:
            raise ParamError(f'{name}.bms12_modules = {modules}: allowed 0..16')
        self.bms12_modules = modules
        extended = config.extended_id
        self.codec = Evms3Codec(self.base_id, bms12_modules=modules,
                                extended_id=True if extended is None else bool(extended),
                                voltage_multiplier=self._multiplier(config))
        self._bms16_marker = False  # latched, as the ZEVA Monitor does
        self._reconfigured(config, config)
        self._chargers = Chargers()  # 1..3: the last command from the EVMS, the last status
        self._status: Evms3Status | None = None
        self._stamp = NAN
        self._current: TimedStore[type, float] = TimedStore()  # wire sign: + = discharge
        self._modules = [Bms12Module() for _ in range(modules)]
        self.reader = ConfigReader(self.lock, self.codec.encode(RequestConfig()))

    # --- configuration ---------------------------------------------------------------------
    @staticmethod
    def _multiplier(config: Evms3Config) -> int:
        return int(config.voltage_multiplier or 1)

    def _config_fields(self, config: Evms3Config) -> ConfigFields:
        multiplier = self._multiplier(config)
        return ConfigFields(evms3_proto.CONFIG_FIELDS,
                            lambda name, value: check_config_value(name, value, multiplier))

    def config_problems(self, config: Evms3Config,
                        keys: Iterable[str] | None = None) -> list[str]:
        """Name every config.* value the EVMS3 protocol refuses (at this voltage multiplier)."""
        return self._config_fields(config).problems(self.name, config, keys)

    def _reconfigured(self, old: Evms3Config, new: Evms3Config) -> None:
        self.module_timeout = max(self.stale_timeout, BMS12_STALE_TIMEOUT)
        self.charger_timeout = max(self.stale_timeout, CHARGER_STALE_TIMEOUT)

    @property
    def frame_ids(self) -> frozenset[tuple[int, bool]]:
        """Return its own IDs at its width and the TC chargers' IDs, always 29-bit."""
        return self.codec.frame_ids

    # --- what the commanding part reads ------------------------------------------------------
    @property
    def status(self) -> Evms3Status | None:
        """Last decoded ID 30 frame (None before the first)."""
        with self.lock:
            return self._status

    @property
    def error(self) -> Evms3Error | None:
        """Return the error code the EVMS reports now (None before the first status)."""
        status = self.status
        return None if status is None else status.error

    @property
    def state(self) -> Evms3State | None:
        """EVMS operating mode now (None before the first status frame)."""
        status = self.status
        return None if status is None else status.state

    def read_config(self, send: SendFrame, timeout: float) -> ReadResult:
        """Send ID 51 through send(frame) -> (ok, why); wait up to timeout s for 52..56."""
        return self.reader.read(send, timeout)

    def read_back(self, port: CallPort) -> tuple[bool, str]:
        """read_config: ask with ID 51, set every config.* parameter from the answer."""
        config = self.config
        return read_back(self.name, self.reader, port, bool(config.config_request),
                         float(config.read_timeout or 2.0))

    # --- the frames the command services send (built here, on the device's own codec) --------
    @staticmethod
    def optional_config(config: Evms3Config) -> tuple[str, ...]:
        """Name the config values a write may leave unset: balance_v unless balancing fixed."""
        return ('balance_v',) if config.config_balance_mode in ('dynamic', 'off') else ()

    def check_writable(self) -> None:
        """
        Refuse (RefusedCommand) unless the EVMS3 reports IDLE or SETUP now and is an EVMS3.

        ZEVA's Monitor offers setup only from IDLE, and the EVMS3 writes its EEPROM with
        interrupts disabled; a BMS16 in its standard form (ID 30 byte 5 = 255) has another
        meaning for the same bytes.
        """
        with self.lock:
            status, marker = self._status, self._bms16_marker
        if marker:
            raise RefusedCommand(
                'the device on ID 30 marks itself as a ZEVA BMS16 (status byte 5 = 255): the '
                'EVMS3 configuration layout would write wrong values into it')
        if status is None:
            raise RefusedCommand('the EVMS3 was never heard (no status frame, ID 30): it '
                                 'must report IDLE or SETUP before a configuration write')
        if self.is_stale():
            raise RefusedCommand(f'the EVMS3 is stale (last state {status.state.name}, no '
                                 'status frame within its stale_timeout): it must report '
                                 'IDLE or SETUP before a configuration write')
        if status.state not in WRITABLE_STATES:
            raise RefusedCommand(
                f'the EVMS3 reports {status.state.name}: its configuration is written only '
                'while it reports IDLE or SETUP (key off, charger unplugged)')

    def config_frames(self) -> list[Frame]:
        """
        Build IDs 36, 32, 33, 34, 35 (the Monitor's order); RefusedCommand if not writable now.

        The EVMS3 saves to EEPROM only when ID 35 arrives, and ID 36 only updates RAM: the
        cell counts go first, so the save on 35 keeps them. One configuration object is read
        once, so a parameter change during the call cannot mix two sets of values.
        """
        self.check_writable()
        config = self.config
        values = self._config_fields(config).complete(
            self.name, config, self.optional_config(config), self.WRITE_HINT.format(self.name))
        cells = values.pop('cells_per_module')
        return [self.codec.encode(BmsCellNumbers(tuple(cells)))] + self.codec.config_frames(
            Evms3Settings.from_mapping(values))

    def sent_ids(self, config: Evms3Config | None = None) -> dict[tuple[int, bool], Sent]:
        """Return IDs 31..38 (setup mode, configuration, acknowledge, SoC reset) and 51."""
        p, extended = evms3_proto, self.codec.is_extended_id
        ids = {(self.codec.base_id + offset, extended): Sent(what) for offset, what in (
            (p.SET_STATE, 'set_setup_mode'), (p.CONFIG1, 'write_config'),
            (p.CONFIG2, 'write_config'), (p.CONFIG3, 'write_config'),
            (p.CONFIG4, 'write_config'), (p.CELL_NUMBERS, 'write_config'),
            (p.ACK_ERROR, 'acknowledge_error'), (p.RESET_SOC, 'reset_soc'))}
        request = self.codec.encode(RequestConfig())
        ids[(request.arbitration_id, request.is_extended_id)] = Sent('read_config request')
        return ids

    def ack_frame(self) -> Frame:
        """Build ID 37 for the error shown now; RefusedCommand if stale or no error."""
        if self.is_stale():
            raise RefusedCommand('the EVMS3 is stale (no status frame within its '
                                 'stale_timeout), so its error is unknown')
        error = self.error
        if error is None or error == Evms3Error.NONE:
            raise RefusedCommand('the EVMS3 reports no error to acknowledge')
        return self.codec.encode(AcknowledgeError(error))

    def reset_soc_frame(self) -> Frame:
        """Build ID 38 (reset SoC to 100 %)."""
        return self.codec.encode(ResetSoc())

    def setup_mode_frame(self, setup: bool) -> Frame:
        """Build ID 31: Setup mode (True) or back to Idle (False)."""
        return self.codec.encode(SetState(setup))

    # --- bus thread --------------------------------------------------------------------------
    def handle_frame(self, arbitration_id: int, data: bytes, stamp: float) -> bool:
        """Decode and apply one frame; a bad 52..56 also fails a read_config waiting now."""
        if arbitration_id not in READBACK_IDS:  # nearly every frame
            return Device.handle_frame(self, arbitration_id, data, stamp)
        malformed = self.frames_malformed
        primary = super().handle_frame(arbitration_id, data, stamp)
        if self.frames_malformed != malformed and arbitration_id in READBACK_IDS:
            with self.lock:
                self.reader.offer_malformed(self.last_malformed)
        return primary

    def _handle(self, reading: Any, stamp: float) -> bool:
        # most frequent first: 3 cell frames a module and second, 4 status frames a second
        if isinstance(reading, Bms12Cells):
            self._modules[reading.module].cells.put(reading.first_cell // 4, reading.voltages_v,
                                                    self.clock())
            return False
        if isinstance(reading, Evms3Status):
            self._status = reading
            self._stamp = stamp
            if reading.bms16_marker:
                self._bms16_marker = True
            return True
        if isinstance(reading, BatteryCurrent):
            self._current.put(BatteryCurrent, reading.current_a, self.clock())
        elif isinstance(reading, Bms12Temperatures):
            self._modules[reading.module].latest.put(
                Bms12Temperatures, reading.temperatures_c, self.clock())  # None: no sensor
        elif isinstance(reading, Bms12Request):
            self._modules[reading.module].latest.put(Bms12Request, reading.balance_mv,
                                                     self.clock())
        elif isinstance(reading, (ChargerCommand, ChargerStatus)):
            self._chargers.offer(reading, self.clock())
        elif isinstance(reading, ConfigReport):
            self.reader.offer(reading, self.clock())
        # Our own commands seen on the bus carry no state.
        return False

    # --- helpers (lock held) -----------------------------------------------------------------
    def _cells_per_module(self) -> list[int]:
        configured = self.config.config_cells_per_module
        if configured is not None and len(configured) >= self.bms12_modules:
            return [min(int(n), CELLS_PER_BMS12) for n in configured[:self.bms12_modules]]
        return [CELLS_PER_BMS12] * self.bms12_modules

    def _capacity_ah(self) -> float:
        capacity = self.config.config_pack_capacity_ah
        if capacity is None or isinstance(capacity, bool):
            return NAN
        return float(capacity) if capacity > 0 else NAN

    def _ros_current(self) -> float:
        current_a = self._current.get(BatteryCurrent, self.clock(), self.stale_timeout)
        return NAN if current_a is None else -current_a

    def _stationary(self) -> bool | None:
        """Stationary mode: the parameter, else the last read-back seen; None = unknown."""
        value = self.config.config_stationary_mode
        if value is not None:
            return bool(value)
        return self.reader.last_values().get('stationary_mode')

    def _silent_modules(self) -> list[int]:
        now = self.clock()
        return [m for m, module in enumerate(self._modules)
                if now - module.last_seen() > self.module_timeout]

    # --- reports: what the engine publishes --------------------------------------------------
    def _battery_report(self) -> BatteryReport:
        current = self._ros_current()
        capacity = self._capacity_ah()
        cells: list[float] = []
        for m, count in enumerate(self._cells_per_module()):
            cells += self._modules[m].cell_voltages(count, self.clock(), self.module_timeout)
        report = BatteryReport(current=current, capacity=capacity, design_capacity=capacity,
                               cell_voltage=cells)
        status = self._status
        if status is None:
            report.power_supply_status = current_status(current)
            return report
        report.stamp = self._stamp
        report.voltage = status.pack_voltage_v
        report.charge = status.amp_hours_ah
        if capacity == capacity:  # NaN while config.pack_capacity_ah is unset
            report.percentage = min(1.0, max(0.0, status.amp_hours_ah / capacity))
        report.temperature = NAN if status.temperature_c is None else float(status.temperature_c)
        report.power_supply_status = (PowerSupplyStatus.CHARGING
                                      if status.state == Evms3State.CHARGING
                                      else current_status(current))
        report.power_supply_health = error_health(status.error, self._stationary())
        report.present = True
        return report

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        status = self._status
        values: dict[str, str] = {}
        if status is None:
            return DiagnosticReport(Level.OK, 'no status frame (ID 30) yet', values)
        if with_values:
            self._values(status, values)
        charger_faults = self._chargers.values(values, self.clock(), self.charger_timeout)
        if with_values:
            values.update(self.reader.values(self.clock()))
        else:
            values = {}  # the chargers' values, filled on the way to their faults
        stationary = self._stationary()
        if status.error == Evms3Error.NONE:
            level = Level.OK
        elif status.error in EVMS3_WARNINGS and not (
                stationary and status.error == Evms3Error.LOW_CELL_WARNING):
            level = Level.WARN
        else:
            level = Level.ERROR
        message = f'{status.state.name}, {error_text(status.error, stationary)}'
        if self._bms16_marker:
            level = max(level, Level.WARN)
            message = ('BMS16 marker heard (ID 30 byte 5 = 255): a ZEVA BMS16, not an EVMS3; '
                       'write_config refused; ' + message)
        silent = self._silent_modules()
        if silent:
            level = max(level, Level.WARN)
            message += '; BMS12 module(s) silent: ' + ', '.join(str(m) for m in silent)
        if charger_faults:
            level = max(level, Level.WARN)
            message += '; ' + '; '.join(charger_faults)
        return DiagnosticReport(level, message, values)

    def _values(self, status: Evms3Status, values: dict[str, str]) -> None:
        """Add the status and every module's values (lock held)."""
        capacity = self._capacity_ah()
        current = self._ros_current()
        values.update({
            'state': status.state.name,
            'error': error_text(status.error, self._stationary()),
            'stationary mode': {True: 'yes', False: 'no', None: 'unknown'}[self._stationary()],
            'error code': str(int(status.error)),
            'amp hours remaining (Ah)': f'{status.amp_hours_ah:.1f}',
            'state of charge (%)': ('unknown: config.pack_capacity_ah unset'
                                    if capacity != capacity
                                    else f'{100 * status.amp_hours_ah / capacity:.1f}'),
            'pack voltage (V)': f'{status.pack_voltage_v:.1f}',
            'aux voltage (V)': ('n/a (255: BMS16 marker)' if status.bms16_marker
                                else f'{status.aux_voltage_v:.1f}'),
            'headlights': 'on' if status.headlights else 'off',
            'isolation (%)': ('not measured' if status.isolation_pct is None
                              else str(status.isolation_pct)),
            'temperature (degC)': ('no sensor' if status.temperature_c is None
                                   else str(status.temperature_c)),
            'current (A, discharge negative)': ('not received (ID 40)' if current != current
                                                else f'{current:.3f}'),
        })
        now = self.clock()
        for m, count in enumerate(self._cells_per_module()):
            self._modules[m].values(m, count, now, self.module_timeout, values)
