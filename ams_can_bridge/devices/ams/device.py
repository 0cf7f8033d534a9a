# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Formula-Student AMS state: status, relays, errors, cells and temperatures, counter health.

The primary frame is the AMS status (base + 0x000). Cells (28 per bank), cell temperatures
(10 per bank) and discharge temperatures (14 per bank) arrive per bank and group every
second; each group goes back to NaN when it has not been heard for ``CELL_STALE_FACTOR``
x ``stale_timeout`` (never a stale number shown as live). Pack voltage (its channel chosen by
``pack_voltage_channel``, U1 by default) and current come from the linked IVT-S when there
is one (``LINKS``: ``current_sensor``, resolved by ``DeviceSet``); without one the voltage is
the sum of the cells once all are received and the current is unknown.

Lock order: the AMS never calls into its IVT-S while holding its own lock. ``battery_report``
reads the IVT-S values first (the IVT-S lock only) and then builds the report under the AMS
lock, so the two locks are never nested and no later IVT -> AMS call can deadlock.

``charge`` is the charge in the battery (sensor_msgs: Ah), never the IVT-S As counter: that
counts from the sensor's last reset and goes negative after a drive. The AMS reports only a
SOC, so ``charge`` = ``design_capacity_ah`` x SOC when that parameter is set, NaN otherwise
(doc/protocols.md section 1).

Health and diagnostics (what the state means, and the error bookkeeping): ``status.py``.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, Iterable, Mapping

from ams_can_bridge.devices.ams.charger import ChargerRepeater
from ams_can_bridge.devices.ams.control import AmsControl
from ams_can_bridge.devices.ams.master import AmsMaster, AmsView
from ams_can_bridge.devices.ams.status import (diagnostic_report, ERROR_STATES, error_text,
                                               health)
from ams_can_bridge.devices.base import (
    BatteryReport, current_status, DiagnosticReport, Device, PowerSupplyStatus)
from ams_can_bridge.devices.generated_configs import AmsConfig
from ams_can_bridge.devices.timed import CounterHealth, TimedSpans, TimedStore
from ams_can_bridge.parameters import ParamSpec
from ams_can_bridge.protocols import ams as proto
from ams_can_bridge.errors import ParamError
from ams_can_bridge.protocols.ams import AmsCodec, AmsError, AmsState
from ams_can_bridge.protocols.ivt_s import IvtMux

NAN = math.nan
# A counter anomaly stays visible (WARN) until this many good status frames followed it.
COUNTER_RECOVERY_FRAMES = 10
# Cells/temperatures are sent every 1 s, the status every 0.1 s: a group is stale after
# this many status stale_timeouts (default 10 x 0.5 s = 5 s = 5 missed cell frames).
CELL_STALE_FACTOR = 10.0
# The IVT-S voltage results one may wire to the pack (ams.pack_voltage_channel).
PACK_VOLTAGE_CHANNELS = ('U1', 'U2', 'U3')


def _or_one(value: Any) -> Any:
    return 1 if value is None else value  # unset: one bank (0 is a value, and refused)


def _bank_count(value: Any, param: str) -> int:
    """Validate the bank_count parameter called param (int 1..5; 3.0 from YAML is 3)."""
    try:
        count = int(value)
        ok = count == float(value) and 1 <= count <= proto.MAX_BANKS
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ParamError(f'{param} = {value!r}: allowed 1..{proto.MAX_BANKS} '
                         '(banks of 28 cells)')
    return count


class _BankArray(TimedSpans):
    """Values of one kind for all 5 possible banks, one timed span per (bank, group)."""

    def __init__(self, per_group: int, groups: int) -> None:
        super().__init__([per_group] * (groups * proto.MAX_BANKS))
        self.groups = groups

    def put_group(self, bank: int, group: int, values: tuple, now: float) -> None:
        self.put((bank - 1) * self.groups + group, values, now)

    def banks(self, banks: int, now: float, max_age: float) -> list[float]:
        """Values of banks 1..banks, NaN where the group was never heard or is too old."""
        return self.read(now, max_age, banks * self.groups)


class AmsDevice(AmsControl, Device[AmsConfig]):
    """Formula-Student AMS (accumulator management system), doc/protocols.md section 1."""

    TYPE = 'ams'
    Config = AmsConfig
    codec: AmsCodec
    BROADCAST_PERIOD = 0.1
    LINKS = {'current_sensor': 'ivt_s'}  # parameter naming the IVT-S -> its device type
    DEFAULT_BASE_ID = proto.DEFAULT_BASE_ID
    PARAMS = [
        ParamSpec('current_sensor', str, '',
                  "name of the ivt_s instance whose current and voltage fill this pack's "
                  "BatteryState ('' = the first ivt_s configured, if any; the parameter "
                  "stays '', the diagnostics name the one used)"),
        ParamSpec('pack_voltage_channel', str, 'U1',
                  'IVT-S voltage result measuring the pack (U1, U2 or U3: how the sensor is '
                  'wired)', choices=PACK_VOLTAGE_CHANNELS),
        ParamSpec('design_capacity_ah', float, None,
                  'pack capacity in Ah: BatteryState design_capacity, and charge = this x '
                  'the AMS SOC; unset = both NaN (the AMS does not report its capacity)',
                  low=0.0, high=100000.0),
        ParamSpec('bank_count', int, 1,
                  'number of banks (28 cells, 10 temperatures, 14 discharge temperatures '
                  'each); also sent to the AMS in every car-status heartbeat',
                  low=1, high=proto.MAX_BANKS, step=1, read_only=False),
    ]

    def __init__(self, name: str, config: AmsConfig | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, config, clock)
        base_id = self.config.base_id
        self.codec = AmsCodec(proto.DEFAULT_BASE_ID if base_id is None else int(base_id))
        self.bank_count = _bank_count(_or_one(self.config.bank_count), f'{name}.bank_count')
        self.master: AmsMaster | None = None  # the car's side, made by attach_senders()
        self.charger: ChargerRepeater | None = None  # the periodic START, attach_senders()
        self._t0 = time.monotonic()  # origin of the charger time tick
        self.current_sensor: Any = None  # an IvtSDevice, linked by DeviceSet (LINKS)
        self.current_sensor_origin = ''  # how it was chosen (diagnostics, start-up log)
        self.state = AmsState.NOT_REPORTED
        self.status_seq = 0
        self.error_seq = 0
        self.last_error: AmsError | None = None
        self._last_error_tick: int | None = None
        self._active_errors: list[AmsError] = []
        self._status: proto.AmsStatus | None = None
        self._stamp = NAN
        # the other periodic frames (charger status, car status, charger command), each
        # expiring on its own after stale_timeout
        self._latest: TimedStore[type, Any] = TimedStore()
        self.counter = CounterHealth(0x100, COUNTER_RECOVERY_FRAMES)  # the status counter
        # the pack values of the IVT-S, read before the AMS lock (lock order, see above)
        self._sensor_pack: tuple[float, float] = (NAN, NAN)
        self._beyond_banks = 0
        self._highest_bank = 0
        self._cells = _BankArray(proto.CELLS_PER_GROUP, proto.CELL_GROUPS)
        self._temps = _BankArray(proto.TEMPS_PER_GROUP, proto.TEMP_GROUPS)
        self._discharge = _BankArray(proto.DISCHARGE_TEMPS_PER_GROUP, proto.TEMP_GROUPS)

    @property
    def arbitration_ids(self) -> frozenset[int]:
        """
        Return the IDs this device listens to: all but the two override frames.

        The charger's aperiodic overrides (base + 0x050/0x051) are commands *to* the AMS,
        and at the default base 0x351 is also the SMA protocol's limits frame: a BMS
        speaking SMA on the same bus would otherwise count as malformed AMS frames.
        """
        return self.codec.arbitration_ids - {
            self.codec.id_of(proto.OVERRIDE_CHARGE_CURRENT),
            self.codec.id_of(proto.OVERRIDE_BANK_COUNT)}

    # --- configuration ---------------------------------------------------------------------
    def attach_current_sensor(self, ivt: Any, origin: str = '') -> None:
        """Use this IVT-S device (current_a / voltage_v) for the pack values."""
        with self.lock:
            self.current_sensor = ivt
            self.current_sensor_origin = origin

    def attach_link(self, key: str, device: Device, origin: str) -> None:
        """Take the device DeviceSet resolved for a LINKS key (only current_sensor)."""
        self.attach_current_sensor(device, origin)

    def config_problems(self, config: AmsConfig,
                        keys: Iterable[str] | None = None) -> list[str]:
        """Refuse a bank count the protocol cannot carry (1..5)."""
        try:
            _bank_count(_or_one(config.bank_count), f'{self.name}.bank_count')
        except ParamError as exc:
            return [str(exc)]
        return []

    def configure(self, changes: Mapping[str, Any]) -> AmsConfig:
        """Apply parameter changes; the master follows period and bank count at once."""
        new = super().configure(changes)
        if self.master is not None:  # outside the device lock: the master reads the state
            self.master.set_period(float(new.heartbeat_period or 0.05))
            self.master.set_bank_count(self.bank_count)
        return new

    def _reconfigured(self, old: AmsConfig, new: AmsConfig) -> None:
        self.bank_count = _bank_count(_or_one(new.bank_count), f'{self.name}.bank_count')

    # --- bus thread ------------------------------------------------------------------------
    def _handle(self, reading: Any, stamp: float) -> bool:
        now = self.clock()
        kind = type(reading)
        if kind is proto.AmsStatus:
            self._on_status(reading, stamp, now)
            return True
        if kind is proto.CellVoltages:
            self._bank_data(self._cells, reading, now)
        elif kind is proto.CellTemperatures:
            self._bank_data(self._temps, reading, now)
        elif kind is proto.DischargeTemperatures:
            self._bank_data(self._discharge, reading, now)
        elif kind is proto.AmsErrorEvent:
            self.error_seq += 1
            self.last_error = reading.error
            self._last_error_tick = reading.time_tick
            if reading.error in self._active_errors:
                self._active_errors.remove(reading.error)
            self._active_errors.append(reading.error)  # most recent last
        elif kind in (proto.AmsChargerStatus, proto.CarStatus, proto.ChargerCommand):
            self._latest.put(kind, reading, now)
        return False

    def handle_frame(self, arbitration_id: int, data: bytes, stamp: float) -> bool:
        """Decode and apply one frame; wake a waiting car command when the AMS answered."""
        master = self.master
        if master is None:  # no car side (commands off, log2bag): nobody waits to be woken
            return Device.handle_frame(self, arbitration_id, data, stamp)
        seen = self.status_seq + self.error_seq  # written by this (the bus) thread only
        primary = Device.handle_frame(self, arbitration_id, data, stamp)
        # after the device lock was released: the master's waiter reads the view under it
        if self.status_seq + self.error_seq != seen:
            master.wake()
        return primary

    def _on_status(self, status: proto.AmsStatus, stamp: float, now: float) -> None:
        # last_seen is still the previous status frame's (the base sets it after _handle):
        # after a silence longer than stale_timeout a restarted counter is no anomaly.
        previous = self.last_seen
        self.counter.observe(status.counter, previous is not None
                             and now - previous <= self.stale_timeout)
        new_state = status.status.state
        if self.state in ERROR_STATES and new_state not in ERROR_STATES:
            self._active_errors.clear()  # the AMS left its error state: errors are history
        self.state = new_state
        self._status = status
        self._stamp = stamp
        self.status_seq += 1

    def _bank_data(self, array: _BankArray, reading: Any, now: float) -> None:
        bank = reading.bank
        if bank > self._highest_bank:
            self._highest_bank = bank
        if bank > self.bank_count:
            self._beyond_banks += 1
        if array is self._cells:
            array.put_group(bank, reading.group, reading.voltages_v, now)
        else:  # floats once per frame here, not per published array
            array.put_group(bank, reading.group, tuple(map(float, reading.temperatures_c)), now)

    # --- what the commanding part waits on ------------------------------------------------
    def active_errors(self) -> list[AmsError]:
        """AMS error events since the AMS last left an error state (oldest first)."""
        with self.lock:
            return list(self._active_errors)

    def master_view(self) -> AmsView:
        """Return the AmsView the AMS master (heartbeat/commands) decides on."""
        with self.lock:
            return AmsView(state=int(self.state), status_seq=self.status_seq,
                           error_seq=self.error_seq, errors=self._error_text(),
                           stale=self.is_stale())

    # --- reports: what the engine publishes (lock held) ------------------------------------
    def _max_cell_age(self) -> float:
        return CELL_STALE_FACTOR * self.stale_timeout

    def _cell_list(self) -> list[float]:
        return self._cells.banks(self.bank_count, self.clock(), self._max_cell_age())

    def _temp_list(self) -> list[float]:
        return self._temps.banks(self.bank_count, self.clock(), self._max_cell_age())

    def battery_report(self) -> BatteryReport:
        """
        Build the BatteryState to publish now (see Device.battery_report).

        The IVT-S values are read first, holding only the IVT-S lock; the AMS lock is taken
        afterwards (lock order: never AMS -> IVT-S, so an IVT-S that some day calls into the
        AMS cannot deadlock against this).
        """
        self._refresh_sensor()
        return super().battery_report()

    def snapshot(self) -> tuple[BatteryReport, dict[str, tuple[int, int, list[float]]]]:
        """Return report and arrays of one moment (Device.snapshot), the IVT-S read first."""
        self._refresh_sensor()
        return super().snapshot()

    def _refresh_sensor(self) -> None:
        # the IVT-S lock alone first, then the AMS lock: never AMS -> IVT-S
        if self.current_sensor is not None:
            pack = self._read_sensor()
            with self.lock:
                self._sensor_pack = pack

    def _read_sensor(self) -> tuple[float, float]:
        """Voltage and current (ROS sign) of the IVT-S; call WITHOUT the AMS lock held."""
        ivt = self.current_sensor
        if ivt is None:
            return NAN, NAN
        channel = IvtMux[str(self.config.pack_voltage_channel or 'U1')]
        return ivt.voltage_v(channel), ivt.current_a()

    def _pack(self) -> tuple[float, float]:
        """Voltage and current (ROS sign): from the IVT-S, else the cell sum and NaN."""
        if self.current_sensor is not None:
            return self._sensor_pack  # read by battery_report() before the lock
        cells = self._cell_list()
        return (math.fsum(cells) if cells else NAN), NAN  # any NaN cell -> NaN sum

    def _design_capacity(self) -> float:
        capacity = self.config.design_capacity_ah
        return NAN if capacity is None else float(capacity)

    def _battery_report(self) -> BatteryReport:
        voltage, current = self._pack()
        temps = [t for t in self._temp_list() if t == t]
        status = self._status
        if temps:
            temperature = float(max(temps))
        else:
            temperature = float(status.temp_max_c) if status else NAN
        soc = status.soc_pct if status else None
        percentage = soc / 100.0 if soc is not None and soc <= 100 else NAN
        capacity = self._design_capacity()
        if self.state is AmsState.CHARGING:
            supply = PowerSupplyStatus.CHARGING
        else:
            supply = current_status(current)
        return BatteryReport(
            stamp=self._stamp, voltage=voltage, current=current,
            charge=capacity * percentage,  # NaN unless both are known
            design_capacity=capacity, temperature=temperature, percentage=percentage,
            power_supply_status=supply,
            power_supply_health=health(status, self.state, self._active_errors),
            present=status is not None, cell_voltage=self._cell_list())

    def _error_text(self) -> str:
        return error_text(self._active_errors)

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        return diagnostic_report(self, with_values)

    def _fresh(self, kind: type) -> Any:
        """Return the last reading of kind (lock held), None if never or not within stale."""
        return self._latest.get(kind, self.clock(), self.stale_timeout)

    def _extra_arrays(self) -> dict[str, tuple[int, int, list[float]]]:
        """Temperatures and discharge temperatures, bank x sensor, NaN until received."""
        banks, now, age = self.bank_count, self.clock(), self._max_cell_age()
        return {
            'temperatures': (banks, proto.TEMPS_PER_BANK,
                             self._temps.banks(banks, now, age)),
            'discharge_temperatures': (banks, proto.DISCHARGE_TEMPS_PER_BANK,
                                       self._discharge.banks(banks, now, age)),
        }
