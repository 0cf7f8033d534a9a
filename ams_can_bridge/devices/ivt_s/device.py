# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
IVT-S current shunt state: latest result of each kind, sign convention, counters, health.

Other devices read it through ``current_a`` and ``voltage_v`` (the AMS fills its pack
BatteryState from them; ``charge_ah``, the As counter, is no charge and only for
diagnostics and tests), so those take the device lock and never return a number
that is unknown, stale or flagged invalid by the sensor (result-error or system-error bit):
NaN instead.

Each result expires on its own, after 5 of its cycles (the cycle the sensor reported for it,
else the interval observed between its frames) and never before ``stale_timeout``: a result
the sensor sends every second is not "stopped" because the current comes every 10 ms. The
current itself, the primary frame, expires after ``stale_timeout`` like the device.

The sensor's configuration is read and written over 0x411/0x511 (devices/ivt_s/exchanges.py),
only from the command services; the answers, whoever asked, show in the diagnostics.

Sign: on the wire the current is positive in whichever direction the shunt is mounted for;
``discharge_positive`` (default true, the common mounting) says which. ROS values follow
sensor_msgs: current and charge are negative while discharging.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import time
from typing import Any, Callable, Mapping

from ams_can_bridge.devices.base import (
    BatteryReport, current_status, DiagnosticReport, Device, Level, PowerSupplyHealth, Sent)
from ams_can_bridge.devices.generated_configs import IvtSConfig
from ams_can_bridge.devices.ivt_s.exchanges import CommandLink
from ams_can_bridge.devices.ivt_s.control import CYCLE_KEYS, ERROR_MASKS_KEY, IvtSControl
from ams_can_bridge.devices.timed import CounterHealth, TimedStore
from ams_can_bridge.errors import ParamError, ProtocolError
from ams_can_bridge.parameters import ParamSpec
from ams_can_bridge.protocols.ivt_s import (
    BYTE_ORDERS, COMMAND_ID, DBC_NAME, DEFAULT_BASE_ID, IvtMux, IvtResult, IvtSCodec,
    RAW_UNIT, RESPONSE_ID, SI_UNIT)
from ams_can_bridge.protocols.ivt_s_commands import (
    CYCLE_MAX_MS, decode_answer, ResultConfig, TriggerMode)

NAN = math.nan
# A counter anomaly keeps the device at WARN until this many good frames of that result
# followed it: one lost frame is visible for a moment, a stuck counter stays visible.
COUNTER_RECOVERY_FRAMES = 16
RESULT_STALE_CYCLES = 5  # a result is unknown after this many of its cycles without a frame
INTERVAL_WEIGHT = 0.25  # weight of each new gap in a result's observed interval
SYSTEM_ERROR_TEXT = ('system error bit (byte 1 bit 7, System_Error: sensor functionality is '
                     'not ensured)')

# The diagnostic keys of each result, in their order (written once: ~80 a report)
_RESULT_KEYS = {kind: tuple(f'{DBC_NAME[kind]}{suffix}' for suffix in (
    f' ({SI_UNIT[kind]})', f' raw ({RAW_UNIT[kind]})', ' counter', ' status', ' counter step',
    ' counter stuck', ' counter jumps', ' age (s)', ' expires after (s)')) for kind in IvtMux}


@dataclass
class _Track:
    """
    Per-result bookkeeping besides the result itself: counter health, frame interval.

    The counter counts the sensor's measurement cycles, not frames (a real sensor's results
    sent every 100 ms advance it by 5, doc/protocols.md 2.1): its step is learned.
    """

    counter: CounterHealth = field(
        default_factory=lambda: CounterHealth(0x10, COUNTER_RECOVERY_FRAMES, step=None))
    interval: float = math.nan  # observed seconds between frames (smoothed)


def _as_bool(key: str, value: Any) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.lower() in ('true', 'false'):
        return value.lower() == 'true'
    raise ParamError(f'{key} = {value!r}: allowed true | false')


class IvtSDevice(IvtSControl, Device[IvtSConfig]):
    """
    Isabellenhuette IVT-S: current, voltages U1..U3, temperature, power, charge, energy.

    The primary frame is the current result (base_id); the device is STALE when it stops.
    BROADCAST_PERIOD 0.1 s: the IVT-S cycle time is set in the sensor (Formula Student
    setups commonly run 10..100 ms); 0.1 s gives a 0.5 s stale_timeout, short enough to
    catch a dead current sensor in a car, and a sensor set to a slower cycle needs a
    larger ``stale_timeout``.
    """

    TYPE = 'ivt_s'
    Config = IvtSConfig
    codec: IvtSCodec
    BROADCAST_PERIOD = 0.1
    DEFAULT_BASE_ID = DEFAULT_BASE_ID
    PARAMS = [
        ParamSpec('byte_order', str, 'big',
                  'byte order of the 32-bit result values: big (factory setting) or little '
                  '(if the sensor was configured so)', choices=BYTE_ORDERS),
        ParamSpec('discharge_positive', bool, True,
                  'true if the IVT-S reports a positive current while the pack discharges '
                  '(depends on how the shunt is mounted); ROS current is negative while '
                  'discharging either way'),
        ParamSpec('command_id', int, COMMAND_ID,
                  'CAN ID the bridge sends IVT-S commands on (factory 0x411); a second IVT-S '
                  'on the same bus needs IDs of its own, set in the sensor and here',
                  low=0, high=0x7FF),
        ParamSpec('answer_id', int, RESPONSE_ID,
                  'CAN ID the IVT-S answers commands on (factory 0x511)', low=0, high=0x7FF),
        ParamSpec('mounted_reversed', bool, False,
                  'true if the IVT-S, with its sign setting normal, reports charging current '
                  'as positive (shunt mounted the other way round); read_config and '
                  'write_config derive the sign setting they expect from this and '
                  'discharge_positive'),
    ]
    COMMAND_PARAMS = [
        ParamSpec(key, int, None,
                  f'cycle time in ms write_config sets for the {DBC_NAME[kind]} result '
                  f'(0 = off); no default: write_config refuses while one is unset',
                  low=0, high=CYCLE_MAX_MS, step=1, read_only=False)
        for kind, key in CYCLE_KEYS.items()] + [
        ParamSpec(ERROR_MASKS_KEY, bool, None,
                  'configuration bit 5, global: true = the sensor sets the measurement / '
                  'system-error status bits (byte 1 bits 6, 7) from its error masks, false = '
                  'only for CRC and Vref errors (factory); write_config writes it to every '
                  'result; unset: write_config keeps what the sensor has (asks it first)',
                  read_only=False),
        ParamSpec('command_timeout', float, 2.0,
                  's each command waits for its answer on 0x511 (STORE at least 2 s)',
                  low=0.1, high=60.0, read_only=False),
        ParamSpec('check_config_at_start', bool, False,
                  'read the sensor configuration once it is heard and report a mismatch with '
                  'byte_order / discharge_positive at once (transmits only while '
                  'commands_enabled is true)'),
    ]

    def __init__(self, name: str, config: IvtSConfig | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(name, config, clock)
        base_id = self.config.base_id
        base_id = DEFAULT_BASE_ID if base_id is None else int(base_id)
        self.byte_order = str(self.config.byte_order or 'big')
        self.discharge_positive = _as_bool(f'{name}.discharge_positive',
                                           True if self.config.discharge_positive is None
                                           else self.config.discharge_positive)
        self.codec = IvtSCodec(base_id, self.byte_order)
        # Wire current/charge -> ROS sign (negative while discharging).
        self._sign = -1.0 if self.discharge_positive else 1.0
        self.mounted_reversed = _as_bool(f'{name}.mounted_reversed',
                                         bool(self.config.mounted_reversed))
        self._results: TimedStore[IvtMux, IvtResult] = TimedStore()  # the last of each kind
        self._tracks: dict[IvtMux, _Track] = {}
        self._stamp = NAN
        self.command_id = COMMAND_ID if self.config.command_id is None \
            else int(self.config.command_id)
        self.answer_id = RESPONSE_ID if self.config.answer_id is None \
            else int(self.config.answer_id)
        if self.answer_id in self.codec.arbitration_ids:
            raise ParamError(f'{name}.answer_id = 0x{self.answer_id:X} is one of its result IDs '
                             f'(base_id 0x{base_id:X}..0x{base_id + 7:X}): give it an ID '
                             'of its own')
        self.link = CommandLink(self.lock, self.command_id)
        self._ids = self.codec.arbitration_ids | {self.answer_id}

    def sent_ids(self, config: IvtSConfig | None = None) -> dict[tuple[int, bool], Sent]:
        """Return the command ID (read_config, write_config, set_running, ...)."""
        return {(self.command_id, False): Sent('IVT-S command')}

    # --- receive side ------------------------------------------------------------------------
    @property
    def arbitration_ids(self) -> frozenset[int]:
        """Return the result IDs and the answer ID (answer_id, factory 0x511)."""
        return self._ids

    def handle_frame(self, arbitration_id: int, data: bytes, stamp: float) -> bool:
        """Decode a result frame, or a 0x511 answer (never primary, never raises)."""
        if arbitration_id != self.answer_id:  # nearly every frame: no super() to look up
            return Device.handle_frame(self, arbitration_id, data, stamp)
        try:
            answer = decode_answer(data)
        except ProtocolError as exc:
            with self.lock:
                self._count_malformed(str(exc))
                self.link.malformed += 1
            return False
        with self.lock:
            self.frames_received += 1
            if isinstance(answer, ResultConfig):
                self._config_answered(answer)
            self.link.offer(answer, self.clock())
        return False

    def _config_answered(self, config: ResultConfig) -> None:
        """Learn a result's counter step again when its cycle (or mode) is new (lock held)."""
        track = self._tracks.get(config.kind)
        known = self.link.configs.get(config.kind)
        if track is not None and (known is None or (known.mode, known.cycle_ms)
                                  != (config.mode, config.cycle_ms)):
            track.counter.restart()

    # --- bus thread ------------------------------------------------------------------------
    def _handle(self, reading: IvtResult, stamp: float) -> bool:
        now = self.clock()
        kind = reading.kind
        previous = self._results.replace(kind, reading, now)  # the previous one's arrival
        track = self._tracks.get(kind)
        if track is None:
            track = self._tracks[kind] = _Track()
            track.counter.observe(reading.counter, False)
        else:
            gap = now - previous
            # After a silence longer than the result's timeout a counter restart is expected.
            # The timeout is never below stale_timeout: a gap within it (every frame of a
            # sensor that keeps sending) needs no timeout worked out (a third of this call).
            track.counter.observe(reading.counter, gap <= self.stale_timeout
                                  or gap <= self._timeout(kind, track))
            track.interval = gap if track.interval != track.interval else (
                track.interval + INTERVAL_WEIGHT * (gap - track.interval))
        if kind is IvtMux.I:
            self._stamp = stamp
            return True
        return False

    # --- values other devices use ------------------------------------------------------------
    def current_a(self) -> float:
        """Pack current in A, ROS sign (negative while discharging); NaN if unknown/stale."""
        with self.lock:
            return self._current_a()

    def voltage_v(self, channel: IvtMux = IvtMux.U1) -> float:
        """Voltage U1 (or U2/U3) in V; NaN if unknown, stale or flagged invalid."""
        with self.lock:
            return self._valid(channel)

    def charge_ah(self) -> float:
        """Charge counter (As / 3600) in Ah, ROS sign like the current; NaN if unknown."""
        with self.lock:
            return self._sign * self._valid(IvtMux.AS) / 3600.0

    def temperature_c(self) -> float:
        """Sensor temperature in degC; NaN if unknown or stale."""
        with self.lock:
            return self._valid(IvtMux.T)

    def latest(self, kind: IvtMux) -> IvtResult | None:
        """Return the last decoded result of one kind (None before any), whatever its age."""
        with self.lock:
            return self._results.latest(IvtMux(kind))

    # --- helpers (lock held) ---------------------------------------------------------------
    def _timeout(self, kind: IvtMux, track: _Track) -> float:
        """
        Seconds after which this result is unknown: 5 of its cycles, >= stale_timeout.

        The current is the primary result: it follows stale_timeout exactly, as the
        device's own staleness does (a slower current cycle needs a larger stale_timeout).
        """
        if kind is IvtMux.I:
            return self.stale_timeout
        config = self.link.configs.get(kind)
        if config is not None and config.mode is TriggerMode.CYCLIC and config.cycle_ms:
            period = config.cycle_ms / 1000.0
        else:
            period = track.interval if track.interval == track.interval else 0.0
        return max(self.stale_timeout, RESULT_STALE_CYCLES * period)

    def _fresh(self, kind: IvtMux) -> IvtResult | None:
        # _handle keeps a result and makes its track in one call: one exists with the other
        entry = self._results.entry(kind)
        if entry is None:
            return None
        result, seen = entry
        silent = self.clock() - seen
        if silent <= self.stale_timeout:  # within any timeout (a dozen calls a report)
            return result
        return result if silent <= self._timeout(kind, self._tracks[kind]) else None

    def _valid(self, kind: IvtMux) -> float:
        """
        SI value (sensor sign) of a fresh result, else NaN.

        A result with its result-error bit (Channel_Error in the vendor DBC) or its
        system-error bit (System_Error) set is no measurement: with the system error "sensor
        functionality is not ensured" (the IVT-S datasheet, result messages).
        """
        result = self._fresh(kind)
        if result is None or result.result_error or result.system_error:
            return NAN
        return result.value

    def _current_a(self) -> float:
        return self._sign * self._valid(IvtMux.I)

    def _fresh_results(self) -> list[IvtResult]:
        return [r for r in map(self._fresh, sorted(self._tracks)) if r is not None]

    # --- reports: what the engine publishes ------------------------------------------------
    def _battery_report(self) -> BatteryReport:
        current = self._current_a()
        results = self._fresh_results()
        if any(r.system_error for r in results):
            health = PowerSupplyHealth.UNSPEC_FAILURE
        elif results:
            health = PowerSupplyHealth.GOOD
        else:
            health = PowerSupplyHealth.UNKNOWN
        return BatteryReport(
            stamp=self._stamp,
            voltage=self._valid(IvtMux.U1),
            current=current,
            # The As result counts since the sensor's last reset (negative after a drive):
            # not the charge in the battery, which the IVT-S does not know.
            charge=NAN,
            temperature=self._valid(IvtMux.T),
            power_supply_status=current_status(current),
            power_supply_health=health,
            present=IvtMux.I in self._tracks,
        )

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        results = self._fresh_results()
        errors, warnings = [], []
        system = [DBC_NAME[r.kind] for r in results if r.system_error]
        if system:
            errors.append(f'{SYSTEM_ERROR_TEXT} on {", ".join(system)}: not used')
        errors += self._config_problems()
        for flag, label in (('ocs', 'over-current (OCS) tripped'),
                            ('result_error', 'result error/out of range'),
                            ('measurement_error', 'measurement error')):
            names = [DBC_NAME[r.kind] for r in results if getattr(r, flag)]
            if names:
                warnings.append(f'{label} ({", ".join(names)})')
        trouble = [DBC_NAME[k] for k, t in sorted(self._tracks.items())
                   if t.counter.in_trouble]
        if trouble:
            warnings.append(f'counter stuck or skipping ({", ".join(trouble)})')
        silent = [DBC_NAME[k] for k in sorted(self._tracks) if k is not IvtMux.I
                  and self._fresh(k) is None]
        if silent:
            warnings.append(f'result stopped ({", ".join(silent)})')
        level = Level.ERROR if errors else Level.WARN if warnings else Level.OK
        current, voltage = self._current_a(), self._valid(IvtMux.U1)
        summary = f'{round(current, 2) + 0.0:.2f} A, {voltage:.1f} V'  # never '-0.00'
        message = '; '.join(errors + warnings + [summary])
        return DiagnosticReport(level, message, self._values(current) if with_values else {})

    def _values(self, current: float) -> dict[str, str]:
        values = {
            'current (A, negative = discharging)': f'{current:.3f}',
            'As counter since sensor reset (Ah, negative = discharged)':
                f'{self._sign * self._valid(IvtMux.AS) / 3600.0:.4f}',
            'power (W, as measured)': f'{self._valid(IvtMux.W):g}',
            'energy (Wh, as measured)': f'{self._valid(IvtMux.WH):g}',
            'byte order': self.byte_order,
            'discharge positive': str(self.discharge_positive).lower(),
        }
        now = self.clock()
        for kind, keys in _RESULT_KEYS.items():
            track = self._tracks.get(kind)
            entry = self._results.entry(kind)
            if track is None or entry is None:  # a track is made with its first result
                values[keys[0]] = 'not received'
                continue
            r, seen = entry
            flags = [label for flag, label in (
                (r.ocs, 'OCS'), (r.result_error, 'result error'),
                (r.measurement_error, 'measurement error'), (r.system_error, 'system error'))
                if flag]
            step = track.counter.step
            for key, value in zip(keys, (
                    f'{r.value:g}', str(r.raw), str(r.counter), ', '.join(flags) or 'ok',
                    'not learned yet' if step is None else str(step),
                    str(track.counter.repeats), str(track.counter.jumps), f'{now - seen:.2f}',
                    f'{self._timeout(kind, track):.2f}')):
                values[key] = value
        values.update(self._command_values())
        return values
