# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Simulated ZEVA EVMS3 with its CAN current sensor and BMS12 cell modules.

What the bus of an EVMS3 conversion carries: the status (ID 30, 4 Hz), the current sensor
(ID 40, 10 Hz), and every 0.5 s the EVMS polls each BMS12 module (t = 0) which answers with
its cells (t = 1..3) and temperatures (t = 4). Remaining Ah integrates the current profile;
pack voltage is the sum of the module cells. Reacts like ZEVA's EVMS3 firmware
(doc/protocols.md section 3): 31 asks for Setup (entered only from IDLE, left on 0; the
request is kept, as the firmware keeps it); 32..35 change the settings in RAM at once and 35
then saves the RAM settings AND the RAM cell counts to EEPROM; 36 changes the cell counts in
RAM only; ``power_cycle()`` reloads RAM from EEPROM, so cell counts sent after the last 35
are lost. 37 clears the matching error, 38 resets SoC to full, 39 powers off (silent until
``power_on()``), 51 is answered from RAM on 52..56 (before any write: ``pack_config()``, the
configuration an installer gave this pack, so that read_config tells the same story as the
status frames; ``faults.extra['config_answer']``: only these IDs of 52..56 are sent, a
partial answer).

States: RUNNING by default (key on, driving; ``state=`` or the simulator's ``--evms3-state``
chooses another to start in). ``key_off()`` parks it in IDLE, where ID 31 puts it into
SETUP and back, and where write_config is accepted; ``key_on()`` drives again.
A status byte 5 of 255 (``bms16_marker``) makes it look like a BMS16 in its standard form.

Charging phase (``start_charging()``, or ``charge_after_s`` after the first tick): the EVMS
enters CHARGING and commands its ``chargers`` TC chargers (1..3, 29-bit) once a second:
target voltage = the stored config's max charge voltage (else 4.15 V per cell), current limit
= its max charge current (else 10 A) shared between the chargers, stop once the pack is full.
Each charger answers once a second with its output (the current tapers over the last 2 V
below the target; the EVMS stops the chargers once it is below 5 % of the limit) and
``faults.extra['charger_status']`` (raw status bits; a charger with a bit set delivers
nothing). While charging the EVMS asks the BMS12 modules to balance to the
lowest cell (dynamic), or to the stored static balance voltage, or not at all ('off').
"""
from __future__ import annotations

import random
from dataclasses import asdict, replace
from typing import Any, Callable, Sequence

from ams_can_bridge.errors import ConfigError, ProtocolError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import (
    AcknowledgeError, BatteryCurrent, Bms12Cells, Bms12Request, Bms12Temperatures,
    BmsCellNumbers, CORE_REQUEST_CONFIG, Evms3Codec, Evms3Settings, Evms3ConfigPart, Evms3Error,
    Evms3State, Evms3Status, PowerOff, RequestConfig, ResetSoc, SetState, ZeroCurrentSensor)
from ams_can_bridge.protocols.tc_charger import ChargerCommand, ChargerStatus
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge.sim.pack import Elapsed, four
from ams_can_bridge.sim.profiles import drive_current_a

CELL_RESISTANCE_OHM = 0.0008
NOMINAL_SERIES_CELLS = 96  # pack voltage when no BMS12 module is simulated
FULL_CELL_V = 4.15
DEFAULT_CHARGE_CURRENT_A = 10.0
CHARGER_PERIOD = 1.0
TAPER_V = 2.0  # the chargers' current falls to 0 over the last TAPER_V below the target
END_FRACTION = 0.05  # charge ends when the current has tapered below 5 % of the limit
CHARGER_TEMPERATURE_RAW = 65
# What an EVMS3 reports before anyone wrote a configuration: the default settings of ZEVA's
# open firmware (MIT, August 2021), in physical units.
FACTORY_CONFIG = Evms3Settings(
    pack_capacity_ah=100, soc_warning_pct=20, full_voltage_v=160, warn_current_a=1210,
    trip_current_a=1210, temp_warning_c=151, min_aux_voltage_v=10, min_isolation_pct=50,
    tacho_ppr=2, fuel_gauge_full_pct=80, fuel_gauge_empty_pct=20, temp_gauge_hot_pct=80,
    temp_gauge_cold_pct=20, bms_min_cell_v=2.5, bms_max_cell_v=3.8, balance_v=None,
    balance_mode='dynamic', bms_hysteresis_v=0.2, bms_min_temp_c=-40, bms_max_temp_c=101,
    max_charge_voltage_v=100, max_charge_current_a=10, alt_charge_voltage_v=100,
    alt_charge_current_a=20, sleep_delay_min=5, mpi_function=0, mpo1_function=0,
    mpo2_function=0, parallel_strings=1, enable_precharge=True, stationary_mode=False,
    reverse_current_display=False, night_brightness=10)


def nmc_cell_ocv(soc: float) -> float:
    """Open-circuit voltage of one NMC-like cell at soc (0..1): 3.30 V empty, 4.15 V full."""
    return 3.3 + 0.85 * min(1.0, max(0.0, soc))


class Evms3Simulator(SimDevice):
    """An EVMS3 on a pack (RUNNING unless told); current_fn(t) -> A, positive = discharge."""

    TYPE = 'evms3'
    STATUS_PERIOD = 0.25
    CURRENT_PERIOD = 0.1
    BMS12_PERIOD = 0.5

    def __init__(self, name: str | None = None, base_id: int = 30, bms12_modules: int = 2,
                 cells_per_module: int | Sequence[int] = 12,
                 current_fn: Callable[[float], float] | None = None,
                 capacity_ah: float = 100.0, seed: int = 0, chargers: int = 1,
                 charge_after_s: float | None = None, extended_id: bool = True,
                 state: Evms3State | str = Evms3State.RUNNING) -> None:
        super().__init__(name)
        if not 0 <= chargers <= 3:
            raise ConfigError(f'chargers {chargers}: allowed 0..3 (TC chargers 1..3)')
        if not 0 <= bms12_modules <= 16:
            raise ConfigError(f'bms12_modules {bms12_modules}: allowed 0..16')
        counts = ([cells_per_module] * bms12_modules if isinstance(cells_per_module, int)
                  else list(cells_per_module)[:bms12_modules])
        if len(counts) != bms12_modules or any(not 0 <= n <= 12 for n in counts):
            raise ConfigError(f'cells_per_module {cells_per_module!r}: 0..12 per module')
        self.codec = Evms3Codec(base_id, bms12_modules=bms12_modules, extended_id=extended_id)
        self.chargers = chargers
        self.charge_after_s = charge_after_s
        self.charger_commands: dict[int, ChargerCommand] = {}  # last sent, per charger
        self.charge_done = False
        self._answer_due = False
        self.bms12_modules = bms12_modules
        self.cells_per_module = counts
        self.current_fn = current_fn or drive_current_a
        self.capacity_ah = float(capacity_ah)
        self.remaining_ah = 0.9 * self.capacity_ah
        rng = random.Random(seed)
        self.cell_offsets_v = [[rng.uniform(-0.012, 0.012) for _ in range(12)]
                               for _ in range(bms12_modules)]
        self.module_temps_c = [(rng.randint(22, 28), rng.randint(22, 28))
                               for _ in range(bms12_modules)]
        self.state = (Evms3State[state.upper()] if isinstance(state, str)
                      else Evms3State(state))
        self.current_a = 0.0  # wire sign: positive = discharge
        self.powered = True
        self.bms16_marker = False
        # EEPROM (None: never written, the factory settings) and RAM (None: as EEPROM)
        self.stored_config: Evms3Settings | None = None
        self.stored_cell_numbers: tuple[int, ...] | None = None
        self._ram: dict[str, Any] | None = None
        self.cell_numbers: tuple[int, ...] | None = None  # RAM (ID 36)
        self.eeprom_writes = 0
        self._set_state_request = 0
        self.received: list[Any] = []  # every command decoded, in order (tests read it)
        self.malformed_received = 0
        self._status = Periodic(self.STATUS_PERIOD)
        self._current = Periodic(self.CURRENT_PERIOD, phase=0.05)
        self._bms12 = Periodic(self.BMS12_PERIOD, phase=0.1)
        self._charger_command = Periodic(CHARGER_PERIOD, phase=0.2)
        self._charger_status = Periodic(CHARGER_PERIOD, phase=0.7)
        self._t0: float | None = None
        self._elapsed = Elapsed()

    # --- model --------------------------------------------------------------------
    def key_off(self) -> None:
        """Switch the ignition off: RUNNING or CHARGING -> IDLE (the EVMS parks)."""
        if self.state in (Evms3State.RUNNING, Evms3State.CHARGING, Evms3State.PRECHARGING):
            self.state = Evms3State.IDLE

    def key_on(self) -> None:
        """Switch the ignition on: IDLE -> RUNNING (a SETUP is left with ID 31 first)."""
        if self.state == Evms3State.IDLE:
            self.state = Evms3State.RUNNING

    def pack_config(self) -> Evms3Settings:
        """
        Return the configuration that fits the simulated pack, in the firmware's steps.

        Capacity as simulated; full and charge voltage at FULL_CELL_V per cell; BMS cell
        limits around the NMC-like cell (3.30 V empty, 4.15 V full); dynamic balancing. The
        other values are the firmware's defaults (FACTORY_CONFIG).
        """
        cells = sum(self.cells_per_module) or NOMINAL_SERIES_CELLS
        full = cells * FULL_CELL_V
        return replace(
            FACTORY_CONFIG,
            pack_capacity_ah=min(1250, max(5, 5 * round(self.capacity_ah / 5))),
            full_voltage_v=min(502, max(10, 2 * round(full / 2))),
            bms_min_cell_v=3.0, bms_max_cell_v=4.2,
            max_charge_voltage_v=min(511, round(full)),  # the firmware counts whole volts
            max_charge_current_a=round(DEFAULT_CHARGE_CURRENT_A),
            alt_charge_voltage_v=min(511, int(cells * 4.0)),
            alt_charge_current_a=round(DEFAULT_CHARGE_CURRENT_A))

    def power_on(self) -> None:
        """Power the EVMS back on after ID 39."""
        self.powered = True

    def power_cycle(self) -> None:
        """Power off and on: RAM settings and cell counts reload from EEPROM, state IDLE."""
        self.powered = True
        self._ram = None if self.stored_config is None else asdict(self.stored_config)
        self.cell_numbers = self.stored_cell_numbers
        self.state = Evms3State.IDLE
        self._set_state_request = 0

    def load(self, config: Evms3Settings, cells: Sequence[int] | None = None) -> None:
        """Start as an EVMS3 configured earlier: config (and cell counts) in EEPROM and RAM."""
        self.stored_config = config
        self.stored_cell_numbers = None if cells is None else tuple(cells)
        self._ram = asdict(config)
        self.cell_numbers = self.stored_cell_numbers
        self.capacity_ah = float(config.pack_capacity_ah)
        self.remaining_ah = min(self.remaining_ah, self.capacity_ah)

    @property
    def ram_config(self) -> Evms3Settings | None:
        """Return the settings in use now (RAM); None = the factory settings, never written."""
        return None if self._ram is None else Evms3Settings(**self._ram)

    def start_charging(self) -> None:
        """Plug the chargers in: the EVMS enters CHARGING and starts commanding them."""
        self.state = Evms3State.CHARGING
        self.charge_done = False

    def charge_command(self, charger: int) -> ChargerCommand:
        """Return what the EVMS asks of one charger now (stop once the pack is full)."""
        cfg = self.ram_config or self.pack_config()
        target = float(cfg.max_charge_voltage_v)
        total = float(cfg.max_charge_current_a)
        # Full: every Ah back in, or the current has tapered to its end (latched: a pack
        # that relaxes after the stop is not charged again).
        self.charge_done = self.charge_done or (
            self.remaining_ah >= self.capacity_ah - 1e-6
            or target - self.pack_voltage_v() < TAPER_V * END_FRACTION)
        return ChargerCommand(charger, min(target, 6553.5), round(total / self.chargers, 1),
                              self.charge_done)

    def charger_output_a(self, charger: int) -> float:
        """Return the current one charger delivers now (A): its limit, tapered, or 0."""
        command = self.charger_commands.get(charger)
        status_bits = int(self.faults.extra.get('charger_status', 0) or 0)
        if command is None or command.stop or status_bits or self.state != Evms3State.CHARGING:
            return 0.0
        headroom = (command.target_voltage_v - self.pack_voltage_v()) / TAPER_V
        return round(command.current_limit_a * min(1.0, max(0.0, headroom)), 1)

    @property
    def soc(self) -> float:
        """State of charge 0..1 (remaining / capacity)."""
        return self.remaining_ah / self.capacity_ah if self.capacity_ah > 0 else 0.0

    @property
    def error(self) -> Evms3Error:
        """Error code reported now (the error_code fault, until acknowledged)."""
        code = self.faults.error_code
        return Evms3Error.NONE if code is None else Evms3Error(code)

    def cell_voltages(self) -> list[list[float]]:
        """Cell voltages per module (V, rounded to the mV the BMS12 reports)."""
        base = nmc_cell_ocv(self.soc) - CELL_RESISTANCE_OHM * self.current_a
        out, index = [], 0
        for m, count in enumerate(self.cells_per_module):
            cells = []
            for c in range(count):
                v = base + self.cell_offsets_v[m][c]
                if index == self.faults.drift_cell:
                    v += self.faults.cell_drift_v
                cells.append(round(min(65.535, max(0.0, v)), 3))
                index += 1
            out.append(cells)
        return out

    def pack_voltage_v(self) -> float:
        """Sum of the module cells (or NOMINAL_SERIES_CELLS cells without modules)."""
        if not any(self.cells_per_module):
            cell = nmc_cell_ocv(self.soc) - CELL_RESISTANCE_OHM * self.current_a
            return NOMINAL_SERIES_CELLS * cell
        return sum(sum(cells) for cells in self.cell_voltages())

    def _follow_set_state_request(self) -> None:
        # EVMS3 main loop: IDLE -> SETUP while the request is > 0, SETUP -> IDLE on 0
        if self.state == Evms3State.IDLE and self._set_state_request > 0:
            self.state = Evms3State.SETUP
        elif self.state == Evms3State.SETUP and self._set_state_request == 0:
            self.state = Evms3State.IDLE

    def _advance(self, now: float) -> None:
        self._follow_set_state_request()
        if self._t0 is None:
            self._t0 = now
        dt = self._elapsed(now)
        if (self.charge_after_s is not None and self.state == Evms3State.RUNNING
                and now - self._t0 >= self.charge_after_s):
            self.start_charging()
        if not self.powered:
            self.current_a = 0.0
        elif self.state == Evms3State.CHARGING:
            # wire sign: positive = discharge, so the chargers' output is negative
            self.current_a = -sum(self.charger_output_a(n) for n in range(1, self.chargers + 1))
        elif self.state == Evms3State.RUNNING:
            self.current_a = float(self.current_fn(now - self._t0))
        else:
            self.current_a = 0.0
        self.remaining_ah = min(self.capacity_ah, max(
            0.0, self.remaining_ah - self.current_a * dt / 3600.0))

    # --- frames out ---------------------------------------------------------------------
    def status(self) -> Evms3Status:
        """Build the ID 30 reading the EVMS would send now."""
        return Evms3Status(
            self.state, self.error, round(min(6553.5, self.remaining_ah), 1),
            round(min(6553.5, self.pack_voltage_v()), 1), 25.5 if self.bms16_marker else 13.2,
            False, 98, round(25 + 0.05 * abs(self.current_a)))

    def tick(self, now: float) -> list[Frame]:
        """Advance the pack and return the frames due at ``now``."""
        self._advance(now)
        frames: list[Frame] = []
        if self._status.due(now):
            frames.append(self.codec.encode(self.status()))
        if self._current.due(now):
            frames.append(self.codec.encode(BatteryCurrent(round(self.current_a, 3))))
        if self._bms12.due(now):
            frames += self._bms12_frames()
        frames += self._charger_frames(now)
        if self._answer_due:
            self._answer_due = False
            frames += self.config_answer()
        if not self.powered or self.faults.silent:
            return []
        if self.faults.malformed:
            frames = [self.corrupt(f) for f in frames]
        return frames

    def _charger_frames(self, now: float) -> list[Frame]:
        charging = self.state == Evms3State.CHARGING and self.chargers > 0
        # Both schedules run always, so the first command and answer come on their phase.
        commands_due = self._charger_command.due(now)
        status_due = self._charger_status.due(now)
        if not charging:
            return []
        frames = []
        if commands_due:
            for n in range(1, self.chargers + 1):
                self.charger_commands[n] = self.charge_command(n)
                frames.append(self.codec.encode(self.charger_commands[n]))
        if status_due:
            bits = int(self.faults.extra.get('charger_status', 0) or 0)
            volts = round(min(6553.5, self.pack_voltage_v()), 1)
            for n in range(1, self.chargers + 1):
                frames.append(self.codec.encode(ChargerStatus(
                    n, volts, self.charger_output_a(n), bits, CHARGER_TEMPERATURE_RAW)))
        return frames

    def config_answer(self) -> list[Frame]:
        """Return the answer to ID 51: IDs 52..56 (only those of a config_answer fault)."""
        cells = self.cell_numbers or tuple(self.cells_per_module) + (0,) * (
            16 - len(self.cells_per_module))
        frames = self.codec.report_frames(self.ram_config or self.pack_config(), cells)
        only = self.faults.extra.get('config_answer')
        if only is None:
            return frames
        wanted = {int(only)} if isinstance(only, (int, str)) else {int(i) for i in only}
        return [f for f in frames if f.arbitration_id in wanted]

    def balance_target_mv(self) -> int | None:
        """Return the balance voltage the EVMS asks of every BMS12 module (None = off)."""
        cfg = self.ram_config
        if cfg is not None and cfg.balance_mode == 'static':
            assert cfg.balance_v is not None  # a static balance mode has its voltage
            return int(round(cfg.balance_v * 1000))
        if self.state != Evms3State.CHARGING or (cfg is not None and cfg.balance_mode == 'off'):
            return None
        cells = [v for module in self.cell_voltages() for v in module]
        return int(round(min(cells) * 1000)) if cells else None  # dynamic: to the lowest

    def _bms12_frames(self) -> list[Frame]:
        balance = self.balance_target_mv()
        frames = []
        for m, cells in enumerate(self.cell_voltages()):
            padded = cells + [0.0] * (12 - len(cells))
            frames.append(self.codec.encode(Bms12Request(m, balance)))
            for first in (0, 4, 8):
                frames.append(self.codec.encode(
                    Bms12Cells(m, first, four(padded[first:first + 4]))))
            frames.append(self.codec.encode(Bms12Temperatures(m, self.module_temps_c[m])))
        return frames

    # --- frames in ----------------------------------------------------------------------
    def on_frame(self, frame: Frame, now: float) -> None:
        """Take commands addressed to the EVMS (IDs 31..39, 41, 51); ignore the rest."""
        if (frame.arbitration_id == CORE_REQUEST_CONFIG
                and frame.is_extended_id == self.codec.is_extended_id):
            self.received.append(RequestConfig())  # any data: the firmware does not look
            self._answer_due = self.powered
            return
        offset = frame.arbitration_id - self.codec.base_id
        if (frame.is_extended_id != self.codec.is_extended_id or not 1 <= offset <= 11
                or offset == 10):
            return  # not ours, or our own status / current sensor frames
        try:
            msg = self.codec.decode(frame.arbitration_id, frame.data)
        except ProtocolError:
            self.malformed_received += 1
            return
        self.received.append(msg)
        if not self.powered:
            return
        if isinstance(msg, SetState):
            self._set_state_request = msg.request or int(msg.setup)
            self._follow_set_state_request()
        elif isinstance(msg, Evms3ConfigPart):
            if self._ram is None:
                self._ram = asdict(self.pack_config())
            self._ram.update(msg.values)  # each packet goes to RAM at once
            if msg.part == 4:  # CORE_RECEIVE_CONFIG4: save RAM (settings + cells) to EEPROM
                self.stored_config = Evms3Settings(**self._ram)
                self.stored_cell_numbers = self.cell_numbers
                self.eeprom_writes += 1
                self.capacity_ah = float(self.stored_config.pack_capacity_ah)
                self.remaining_ah = min(self.remaining_ah, self.capacity_ah)
        elif isinstance(msg, BmsCellNumbers):
            self.cell_numbers = msg.cells_per_module  # RAM only
        elif isinstance(msg, AcknowledgeError):
            if self.faults.error_code is not None and msg.error == self.faults.error_code:
                self.faults.error_code = None
        elif isinstance(msg, ResetSoc):
            self.remaining_ah = self.capacity_ah
        elif isinstance(msg, PowerOff):
            self.powered = False
        elif isinstance(msg, ZeroCurrentSensor):
            pass  # the simulated sensor has no offset to zero
