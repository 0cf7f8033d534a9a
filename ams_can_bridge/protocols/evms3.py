"""
ZEVA EVMS3 and its BMS12 cell modules: 29-bit frames <-> typed readings and commands.

PROTOCOLS.md section 3 (EVMS3 CAN protocol rev 1.1; BMS12 from ZEVA's open firmware).
IDs of the EVMS3 are ``base_id + 0..11`` (30 status .. 41 zero current sensor by default);
BMS12 module ``m`` uses ``300 + 10 m + t`` (t = 0 request, 1..3 cells, 4 temperatures).
29-bit by default; ``extended_id=False`` for a firmware built with 11-bit IDs. The TC chargers
the EVMS drives (``protocols.tc_charger``, always 29-bit) are decoded here too.
msg_defs/evms3.dbc describes the same frames for other tools; this codec is written by hand
because it runs on the bus thread for every frame (a few microseconds, no cantools), and
because the DBC cannot carry what is done here: the 9th bit of the charge voltages, the
balance special values (251 dynamic, 252 off) and refusing, instead of clamping, any
configuration value the EVMS would silently limit.

This module stays long on purpose: the whole wire format of one device in one place.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field, fields
from typing import Any, Iterable, Mapping, Sequence

from ams_can_bridge.protocols.common import (
    check_dlc, check_range, ConfigField, EncodeRangeError, Frame, MalformedFrameError)
from ams_can_bridge.protocols.tc_charger import (
    CHARGER_IDS, ChargerCommand, ChargerStatus, TcChargerCodec)

BMS12_BASE_ID = 300
BMS12_MAX_MODULES = 16
CURRENT_OFFSET_MA = 8388608
STATUS, SET_STATE, CONFIG1, CONFIG2, CONFIG3, CONFIG4 = range(6)
CELL_NUMBERS, ACK_ERROR, RESET_SOC, POWER_OFF, BATTERY_CURRENT, ZERO_CURRENT = range(6, 12)
BALANCE_DYNAMIC = 251
BALANCE_OFF = 252
# Read-back (ZEVA's open firmware, MIT, August 2021): fixed IDs, not moved by base_id. ID 51
# is also a ZEVA motor controller's throttle frame (MC_SET_THROTTLE_ID), 52/53 its settings.
CORE_REQUEST_CONFIG = 51
CORE_SEND_CONFIG1, CORE_SEND_CONFIG2, CORE_SEND_CONFIG3, CORE_SEND_CONFIG4 = range(52, 56)
CORE_SEND_CELL_NUMS = 56
READBACK_IDS = range(CORE_SEND_CONFIG1, CORE_SEND_CELL_NUMS + 1)
READBACK_NAMES = {52: 'config 1', 53: 'config 2', 54: 'config 3', 55: 'config 4',
                  56: 'cell numbers'}


class Evms3State(enum.IntEnum):
    """Status byte bits 2..0."""

    IDLE = 0
    PRECHARGING = 1
    RUNNING = 2
    CHARGING = 3
    STOPPED = 4
    SETUP = 5


class Evms3Error(enum.IntEnum):
    """Status byte bits 7..3 (vendor names)."""

    NONE = 0
    CORRUPT_SETTINGS = 1
    OVERCURRENT_WARNING = 2
    OVERCURRENT_SHUTDOWN = 3
    LOW_CELL_WARNING = 4
    BMS_SHUTDOWN = 5  # undervoltage cell for 10+ s
    HIGH_CELL_WARNING = 6
    BMS_ENDED_CHARGE = 7  # overvoltage cell for > 1 s
    BMS_OVER_TEMP = 8
    BMS_UNDER_TEMP = 9
    LOW_SOC_WARNING = 10
    OVERTEMPERATURE = 11  # the EVMS core's own sensor
    ISOLATION_ERROR = 12
    LOW_12V = 13
    PRECHARGE_FAILED = 14
    CONTACTOR_SWITCH_ERROR = 15
    CAN_ERROR = 16


EVMS3_WARNINGS = frozenset({2, 4, 6, 10})
_STATES = tuple(Evms3State)
_ERRORS = tuple(Evms3Error)


# --- readings and commands ------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Evms3Status:
    """ID 30: the EVMS broadcast (4 Hz)."""

    state: Evms3State
    error: Evms3Error
    amp_hours_ah: float  # remaining
    pack_voltage_v: float
    aux_voltage_v: float
    headlights: bool
    isolation_pct: int | None  # None: could not be measured (raw 101)
    temperature_c: int | None  # None: no sensor (raw 0)


@dataclass(frozen=True, slots=True)
class SetState:
    """ID 31: enter Setup (True) or return to Idle (False)."""

    setup: bool


@dataclass(frozen=True)
class Evms3Config:
    """IDs 32..35: every configuration value, physical units (ranges in CONFIG_FIELDS)."""

    pack_capacity_ah: int
    soc_warning_pct: int
    full_voltage_v: int
    warn_current_a: int
    trip_current_a: int
    temp_warning_c: int
    min_aux_voltage_v: int
    min_isolation_pct: int
    tacho_ppr: int
    fuel_gauge_full_pct: int
    fuel_gauge_empty_pct: int
    temp_gauge_hot_pct: int
    temp_gauge_cold_pct: int
    bms_min_cell_v: float
    bms_max_cell_v: float
    balance_v: float | None  # used only when balance_mode is 'static'
    balance_mode: str
    bms_hysteresis_v: float
    bms_min_temp_c: int
    bms_max_temp_c: int
    max_charge_voltage_v: int
    max_charge_current_a: int
    alt_charge_voltage_v: int
    alt_charge_current_a: int
    sleep_delay_min: int
    mpi_function: int
    mpo1_function: int
    mpo2_function: int
    parallel_strings: int
    enable_precharge: bool
    stationary_mode: bool

    @classmethod
    def from_parts(cls, parts: Iterable['Evms3ConfigPart']) -> 'Evms3Config':
        """Join the four decoded packets (any order) into one configuration."""
        values: dict[str, Any] = {}
        for part in parts:
            values.update(part.values)
        return cls(**values)

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> 'Evms3Config':
        """Build from a name -> value mapping (extra keys ignored, missing ones named)."""
        names = [f.name for f in fields(cls)]
        missing = [n for n in names if n not in values and n != 'balance_v']
        if missing:
            raise EncodeRangeError(missing[0], None, 'a value (unset: ' + ', '.join(missing) + ')')
        return cls(**{n: values.get(n) for n in names})


@dataclass(frozen=True)
class Evms3ConfigPart:
    """One decoded configuration packet: part 1..4 (IDs 32..35) and its values by name."""

    part: int
    values: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class BmsCellNumbers:
    """ID 36: cells per BMS12 module, 16 values 0..15."""

    cells_per_module: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class AcknowledgeError:
    """ID 37: acknowledge this error code."""

    error: Evms3Error


@dataclass(frozen=True, slots=True)
class ResetSoc:
    """
    ID 38: reset the state of charge to 100 % (sent with DLC 0).

    ZEVA's 2021 firmware reads one data byte 0..100 as the SoC to set; older firmware
    ignores the data and sets 100 %. The bridge sends no data, so both mean 100 %.
    """


@dataclass(frozen=True, slots=True)
class RequestConfig:
    """ID 51 (DLC 0): ask the EVMS for its whole configuration; it answers on 52..56."""


@dataclass(frozen=True)
class ConfigReport:
    """IDs 52..56: one packet of the configuration the EVMS reports (its answer to 51)."""

    arbitration_id: int  # 52..55: the layout of 32..35; 56: the layout of 36
    values: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ConfigReadback:
    """A whole reported configuration (52..56 joined), or what was missing from it."""

    config: Evms3Config | None
    cells_per_module: tuple[int, ...] | None
    missing: tuple[int, ...] = ()  # IDs of 52..56 not received

    @classmethod
    def join(cls, reports: Iterable[ConfigReport]) -> 'ConfigReadback':
        """Join the packets of one answer (any order); missing IDs named, nothing guessed."""
        by_id = {r.arbitration_id: r for r in reports}
        missing = tuple(i for i in READBACK_IDS if i not in by_id)
        if missing:
            return cls(None, None, missing)
        values: dict[str, Any] = {}
        for report in by_id.values():
            values.update(report.values)
        cells = values.pop('cells_per_module')
        return cls(Evms3Config(**values), tuple(cells))

    def parameter_values(self) -> dict[str, Any]:
        """Every configuration field read, physical units (balance_v only when static)."""
        if self.config is None or self.cells_per_module is None:
            return {}
        values = {f.name: getattr(self.config, f.name) for f in fields(Evms3Config)}
        if values['balance_v'] is None:
            del values['balance_v']  # dynamic / off: the device reported no voltage
        values['cells_per_module'] = list(self.cells_per_module)
        return values

    def summary(self) -> str:
        """One line: capacity, limits, balancing, charging, modules."""
        cfg = self.config
        if cfg is None or self.cells_per_module is None:
            return 'incomplete: missing ' + ', '.join(
                f'ID {i} ({READBACK_NAMES[i]})' for i in self.missing)
        balance = (f'static {cfg.balance_v:.2f} V' if cfg.balance_mode == 'static'
                   else cfg.balance_mode)
        modules = [n for n in self.cells_per_module if n]
        return (f'{cfg.pack_capacity_ah} Ah, full {cfg.full_voltage_v} V, cells '
                f'{cfg.bms_min_cell_v:.2f}..{cfg.bms_max_cell_v:.2f} V, balance {balance}, '
                f'charge {cfg.max_charge_voltage_v} V {cfg.max_charge_current_a} A, '
                f'{len(modules)} BMS12 module(s) with {sum(modules)} cells')


@dataclass(frozen=True, slots=True)
class PowerOff:
    """ID 39: power the EVMS off."""


@dataclass(frozen=True, slots=True)
class BatteryCurrent:
    """ID 40: battery current from the current sensor, A, positive = discharge."""

    current_a: float


@dataclass(frozen=True, slots=True)
class ZeroCurrentSensor:
    """ID 41: zero the current sensor."""


@dataclass(frozen=True, slots=True)
class Bms12Request:
    """BMS12 t=0 (EVMS -> module): balance (shunt) voltage in mV, None = no balancing."""

    module: int
    balance_mv: int | None


@dataclass(frozen=True, slots=True)
class Bms12Cells:
    """BMS12 t=1..3: four cell voltages (V) starting at cell index first_cell (0, 4, 8)."""

    module: int
    first_cell: int
    voltages_v: tuple[float, float, float, float]


@dataclass(frozen=True, slots=True)
class Bms12Temperatures:
    """BMS12 t=4: the module's two temperatures (degC)."""

    module: int
    temperatures_c: tuple[int, int]


# --- configuration table ----------------------------------------------------------------------
# Plain byte fields: (name, type, packet 0..3, byte, scale, offset, raw low, raw high, unit, what)
_LINEAR = (
    ('pack_capacity_ah', int, 0, 0, 5, 0, 1, 250, 'Ah', 'pack capacity'),
    ('soc_warning_pct', int, 0, 1, 1, 0, 0, 99, '%', 'state of charge warning level'),
    ('full_voltage_v', int, 0, 2, 2, 0, 5, 251, 'V', 'pack voltage that counts as full'),
    ('warn_current_a', int, 0, 3, 10, 0, 1, 121, 'A', 'overcurrent warning threshold'),
    ('trip_current_a', int, 0, 4, 10, 0, 1, 121, 'A', 'overcurrent shutdown threshold'),
    ('temp_warning_c', int, 0, 5, 1, 0, 0, 151, 'degC', 'EVMS temperature warning'),
    ('min_aux_voltage_v', int, 0, 6, 1, 0, 8, 15, 'V', 'minimum 12 V (aux) voltage'),
    ('min_isolation_pct', int, 0, 7, 1, 0, 0, 99, '%', 'minimum isolation integrity'),
    ('tacho_ppr', int, 1, 0, 1, 0, 1, 6, '', 'tachometer pulses per revolution'),
    ('fuel_gauge_full_pct', int, 1, 1, 1, 0, 0, 100, '%', 'fuel gauge output when full'),
    ('fuel_gauge_empty_pct', int, 1, 2, 1, 0, 0, 100, '%', 'fuel gauge output when empty'),
    ('temp_gauge_hot_pct', int, 1, 3, 1, 0, 0, 100, '%', 'temperature gauge output hot'),
    ('temp_gauge_cold_pct', int, 1, 4, 1, 0, 0, 100, '%', 'temperature gauge output cold'),
    ('bms_min_cell_v', float, 1, 5, 0.01, 1.5, 0, 250, 'V', 'BMS minimum cell voltage'),
    ('bms_max_cell_v', float, 1, 6, 0.01, 2.0, 0, 250, 'V', 'BMS maximum cell voltage'),
    ('bms_hysteresis_v', float, 2, 0, 0.01, 0, 0, 50, 'V', 'BMS hysteresis'),
    ('bms_min_temp_c', int, 2, 1, 1, -40, 0, 141, 'degC', 'BMS minimum temperature'),
    ('bms_max_temp_c', int, 2, 2, 1, -40, 0, 141, 'degC', 'BMS maximum temperature'),
    ('sleep_delay_min', int, 2, 7, 1, 0, 1, 6, 'min', 'sleep delay'),
    ('mpi_function', int, 3, 0, 1, 0, 0, 3, '', 'MPI function (EVMS3 manual order)'),
    ('mpo1_function', int, 3, 1, 1, 0, 0, 6, '', 'MPO1 function (EVMS3 manual order)'),
    ('mpo2_function', int, 3, 2, 1, 0, 0, 6, '', 'MPO2 function (EVMS3 manual order)'),
    ('parallel_strings', int, 3, 3, 1, 0, 1, 20, '', 'parallel strings'),
)
_LINEAR_BY_NAME = {row[0]: row for row in _LINEAR}
# 9-bit voltage (low byte + bit 7 of the current byte) and 7-bit current, packet 3 bytes 3..6
_CHARGE = (('max_charge_voltage_v', 'max_charge_current_a', 3),
           ('alt_charge_voltage_v', 'alt_charge_current_a', 5))
_BOOLS = (('enable_precharge', 4), ('stationary_mode', 5))  # packet 4 (ID 35)
BALANCE_MODES = ('static', 'dynamic', 'off')


def _linear_field(row: tuple) -> ConfigField:
    name, typ, _, _, scale, offset, rlo, rhi, unit, what = row
    low, high = _phys(typ, scale, offset, rlo), _phys(typ, scale, offset, rhi)
    return ConfigField(name, typ, low, high, scale, unit, f'{what} ({low:g}..{high:g} {unit})'
                       .replace(' )', ')'))


def _phys(typ: type, scale: float, offset: float, raw: int) -> float:
    if typ is int:
        return int(raw * scale + offset)
    return round(raw * scale + offset, 6)


def _build_fields() -> tuple[ConfigField, ...]:
    by_name = {row[0]: _linear_field(row) for row in _LINEAR}
    by_name['balance_v'] = ConfigField(
        'balance_v', float, 2.0, 4.5, 0.01, 'V',
        'static balance voltage (2.00..4.50 V), used only when balance_mode is static')
    by_name['balance_mode'] = ConfigField(
        'balance_mode', str, description='balancing: static (at balance_v), dynamic or off',
        choices=BALANCE_MODES)
    for volt, amp, _ in _CHARGE:
        kind = volt.split('_')[0]
        by_name[volt] = ConfigField(volt, int, 0, 511, 1, 'V', f'{kind} charge voltage (0..511 V)')
        by_name[amp] = ConfigField(amp, int, 0, 127, 1, 'A', f'{kind} charge current (0..127 A)')
    by_name['enable_precharge'] = ConfigField('enable_precharge', bool,
                                              description='enable the precharge sequence')
    by_name['stationary_mode'] = ConfigField('stationary_mode', bool,
                                             description='stationary (non-vehicle) mode')
    ordered = [by_name[f.name] for f in fields(Evms3Config)]
    ordered.append(ConfigField('cells_per_module', 'int[]', 0, 15, 1, '',
                               'cells on each of the 16 BMS12 modules (0..15), ID 36',
                               length=BMS12_MAX_MODULES))
    return tuple(ordered)


CONFIG_FIELDS: tuple[ConfigField, ...] = _build_fields()
_FIELD_BY_NAME = {f.name: f for f in CONFIG_FIELDS}


def check_config_value(name: str, value: Any) -> Any:
    """
    Validate one configuration value; return it normalized (int/float/bool/str/tuple).

    Raises EncodeRangeError naming the field, the value and what is allowed. Numbers may be
    written as int or float (3 and 3.0 are the same); nothing is clamped.
    """
    spec = _FIELD_BY_NAME.get(name)
    if spec is None:
        raise EncodeRangeError(name, value, 'one of ' + ', '.join(_FIELD_BY_NAME))
    if spec.type is bool:
        if isinstance(value, bool) or (isinstance(value, int) and value in (0, 1)):
            return bool(value)
        raise EncodeRangeError(name, value, 'true or false')
    if spec.type is str:
        if value not in spec.choices:
            raise EncodeRangeError(name, value, 'one of ' + ', '.join(spec.choices))
        return value
    if spec.type == 'int[]':
        if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) \
                or len(value) != spec.length:
            raise EncodeRangeError(name, value, f'{spec.length} integers 0..15')
        return tuple(int(_number(f'{name}[{i}]', v, spec)) for i, v in enumerate(value))
    number = _number(name, value, spec)
    return int(round(number)) if spec.type is int else round(float(number), 6)


def _number(name: str, value: Any, spec: ConfigField) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise EncodeRangeError(name, value, f'a number {spec.low:g}..{spec.high:g} {spec.unit}'
                               .rstrip())
    check_range(name, value, spec.low, spec.high, spec.step, spec.unit)
    return value


def _config_payloads(cfg: Evms3Config) -> list[bytearray]:
    out = [bytearray(8) for _ in range(4)]
    for name, _, packet, byte, scale, offset, _, _, _, _ in _LINEAR:
        value = check_config_value(name, getattr(cfg, name))
        out[packet][byte] = int(round((value - offset) / scale))
    mode = check_config_value('balance_mode', cfg.balance_mode)
    if mode == 'static' or cfg.balance_v is not None:
        balance = check_config_value('balance_v', cfg.balance_v)
    out[1][7] = (BALANCE_DYNAMIC if mode == 'dynamic' else BALANCE_OFF if mode == 'off'
                 else int(round((balance - 2.0) / 0.01)))
    for volt, amp, byte in _CHARGE:
        v = check_config_value(volt, getattr(cfg, volt))
        a = check_config_value(amp, getattr(cfg, amp))
        out[2][byte] = v & 0xFF
        out[2][byte + 1] = a | (v >> 8) << 7
    for name, byte in _BOOLS:
        out[3][byte] = int(check_config_value(name, getattr(cfg, name)))
    return out


def _decode_config(packet: int, aid: int, data: bytes) -> Evms3ConfigPart:
    values: dict[str, Any] = {}
    for name, typ, pk, byte, scale, offset, rlo, rhi, _, _ in _LINEAR:
        if pk != packet:
            continue
        raw = data[byte]
        if not rlo <= raw <= rhi:
            raise MalformedFrameError(aid, data, f'{name} raw {raw} outside {rlo}..{rhi}')
        values[name] = _phys(typ, scale, offset, raw)
    if packet == 1:
        raw = data[7]
        if raw > BALANCE_OFF:
            raise MalformedFrameError(aid, data, f'balance voltage raw {raw} outside 0..252')
        values['balance_mode'] = ('dynamic' if raw == BALANCE_DYNAMIC else
                                  'off' if raw == BALANCE_OFF else 'static')
        values['balance_v'] = round(2.0 + raw * 0.01, 2) if raw <= 250 else None
    elif packet == 2:
        for volt, amp, byte in _CHARGE:
            values[volt] = data[byte] | (data[byte + 1] >> 7) << 8
            values[amp] = data[byte + 1] & 0x7F
    elif packet == 3:
        for name, byte in _BOOLS:
            if data[byte] > 1:
                raise MalformedFrameError(aid, data, f'{name} raw {data[byte]}, expected 0 or 1')
            values[name] = bool(data[byte])
    return Evms3ConfigPart(packet + 1, values)


# --- the codec -------------------------------------------------------------------------------
class Evms3Codec:
    """EVMS3 frames at base_id + 0..11, BMS12 modules 0..bms12_modules-1, TC chargers 1..3."""

    def __init__(self, base_id: int = 30, bms12_modules: int = BMS12_MAX_MODULES,
                 bms12_base: int = BMS12_BASE_ID, extended_id: bool = True) -> None:
        """Decode/encode at base_id (+ the fixed read-back IDs 51..56); ValueError on overlap."""
        # ZEVA's firmware uses 29-bit IDs unless built with USE_29BIT_IDS 0; the TC chargers
        # on the same bus always use 29-bit IDs, so one EVMS3 may need both widths.
        top = 0x1FFFFFFF if extended_id else 0x7FF
        if not 0 <= base_id <= top - 11:
            raise ValueError(f'base_id {base_id} outside 0..0x{top - 11:X} '
                             f'({29 if extended_id else 11}-bit IDs)')
        if not 0 <= bms12_modules <= BMS12_MAX_MODULES:
            raise ValueError(f'bms12_modules {bms12_modules} outside 0..16')
        self.is_extended_id = bool(extended_id)
        self.base_id = base_id
        self.bms12_base = bms12_base
        self.bms12_modules = bms12_modules
        self._bms12 = {bms12_base + 10 * m + t: (m, t)
                       for m in range(bms12_modules) for t in range(5)}
        own = set(range(base_id, base_id + 12))
        if own & set(self._bms12):
            raise ValueError(f'EVMS3 IDs {base_id}..{base_id + 11} overlap the BMS12 IDs '
                             f'{bms12_base}..{bms12_base + 10 * bms12_modules - 6}')
        fixed = set(range(CORE_REQUEST_CONFIG, CORE_SEND_CELL_NUMS + 1))
        if fixed & (own | set(self._bms12)):
            raise ValueError(f'EVMS3 IDs {base_id}..{base_id + 11} or the BMS12 IDs overlap '
                             'the read-back IDs 51..56 (fixed in the EVMS3 firmware)')
        own |= set(READBACK_IDS)  # 51 is not listened to: on a ZEVA bus it may be throttle
        self.chargers = TcChargerCodec()
        self.arbitration_ids = frozenset(own | set(self._bms12) | CHARGER_IDS)
        # (ID, 29-bit) pairs: the node dispatches on both, so an 11-bit EVMS3 still gets its
        # chargers' 29-bit frames and no 29-bit frame with an EVMS3 number reaches it.
        self.frame_ids = frozenset({(i, self.is_extended_id) for i in own | set(self._bms12)}
                                   | {(i, True) for i in CHARGER_IDS})
        b = base_id
        self._decoders = {
            b + STATUS: self._decode_status, b + SET_STATE: self._decode_set_state,
            b + CELL_NUMBERS: self._decode_cell_numbers, b + ACK_ERROR: self._decode_ack,
            b + RESET_SOC: lambda aid, data: ResetSoc(),
            b + POWER_OFF: self._decode_empty, b + ZERO_CURRENT: self._decode_empty,
            b + BATTERY_CURRENT: self._decode_current,
        }
        for packet in range(4):
            self._decoders[b + CONFIG1 + packet] = self._decode_config
            self._decoders[CORE_SEND_CONFIG1 + packet] = self._decode_report
        self._decoders[CORE_SEND_CELL_NUMS] = self._decode_report

    # --- decode ---------------------------------------------------------------------------
    def decode(self, arbitration_id: int, data: bytes) -> Any:
        """Frame -> reading; MalformedFrameError for a wrong DLC, impossible value or ID."""
        decoder = self._decoders.get(arbitration_id)
        if decoder is not None:
            return decoder(arbitration_id, data)
        module_type = self._bms12.get(arbitration_id)
        if module_type is None:
            if arbitration_id in CHARGER_IDS:
                return self.chargers.decode(arbitration_id, data)
            raise MalformedFrameError(arbitration_id, data, 'not an EVMS3/BMS12 ID of this codec')
        return self._decode_bms12(arbitration_id, data, *module_type)

    def _decode_status(self, aid: int, data: bytes) -> Evms3Status:
        if len(data) != 8:
            check_dlc(aid, data, 8)
        b0 = data[0]
        state, error = b0 & 0x07, b0 >> 3
        if state > 5:
            raise MalformedFrameError(aid, data, f'unknown state {state} (0..5)')
        if error > 16:
            raise MalformedFrameError(aid, data, f'unknown error code {error} (0..16)')
        iso = data[6] & 0x7F
        if iso > 101:
            raise MalformedFrameError(aid, data, f'isolation {iso} % (0..100, 101 = n/a)')
        temp = data[7]
        return Evms3Status(_STATES[state], _ERRORS[error], (data[1] << 8 | data[2]) / 10,
                           (data[3] << 8 | data[4]) / 10, data[5] / 10, data[6] >= 0x80,
                           None if iso == 101 else iso, temp - 40 if temp else None)

    def _decode_set_state(self, aid: int, data: bytes) -> SetState:
        check_dlc(aid, data, 1)
        if data[0] > 1:
            raise MalformedFrameError(aid, data, f'set state {data[0]}, expected 0 or 1')
        return SetState(bool(data[0]))

    def _decode_config(self, aid: int, data: bytes) -> Evms3ConfigPart:
        packet = aid - self.base_id - CONFIG1
        # ID 35: the seed calls it "6 bytes" but draws 8 (two reserved): accept both.
        check_dlc(aid, data, (6, 8) if packet == 3 else 8)
        return _decode_config(packet, aid, data)

    def _decode_report(self, aid: int, data: bytes) -> ConfigReport:
        if aid == CORE_SEND_CELL_NUMS:
            cells = self._decode_cell_numbers(aid, data).cells_per_module
            return ConfigReport(aid, {'cells_per_module': cells})
        packet = aid - CORE_SEND_CONFIG1
        check_dlc(aid, data, (6, 8) if packet == 3 else 8)
        return ConfigReport(aid, _decode_config(packet, aid, data).values)

    def _decode_cell_numbers(self, aid: int, data: bytes) -> BmsCellNumbers:
        check_dlc(aid, data, 8)
        return BmsCellNumbers(tuple((data[m >> 1] >> (4 * (m & 1))) & 0x0F for m in range(16)))

    def _decode_ack(self, aid: int, data: bytes) -> AcknowledgeError:
        check_dlc(aid, data, 1)
        if data[0] > 16:
            raise MalformedFrameError(aid, data, f'unknown error code {data[0]} (0..16)')
        return AcknowledgeError(_ERRORS[data[0]])

    def _decode_empty(self, aid: int, data: bytes) -> PowerOff | ZeroCurrentSensor:
        check_dlc(aid, data, 0)
        return PowerOff() if aid - self.base_id == POWER_OFF else ZeroCurrentSensor()

    def _decode_current(self, aid: int, data: bytes) -> BatteryCurrent:
        if len(data) != 3:
            check_dlc(aid, data, 3)
        return BatteryCurrent(((data[0] << 16 | data[1] << 8 | data[2]) - CURRENT_OFFSET_MA)
                              / 1000)

    def _decode_bms12(self, aid: int, data: bytes, module: int, t: int) -> Any:
        if t == 0:
            check_dlc(aid, data, 2)
            mv = data[0] << 8 | data[1]
            return Bms12Request(module, mv or None)
        if t == 4:
            # The BMS12 PDF says DLC 2; ZEVA's firmware sends 8 with zero padding.
            check_dlc(aid, data, (2, 8))
            return Bms12Temperatures(module, (data[0] - 40, data[1] - 40))
        if len(data) != 8:
            check_dlc(aid, data, 8)
        return Bms12Cells(module, 4 * (t - 1), (
            (data[0] << 8 | data[1]) / 1000, (data[2] << 8 | data[3]) / 1000,
            (data[4] << 8 | data[5]) / 1000, (data[6] << 8 | data[7]) / 1000))

    # --- encode ---------------------------------------------------------------------------
    def _frame(self, offset: int, data: bytes | bytearray) -> Frame:
        return Frame(self.base_id + offset, bytes(data), self.is_extended_id)

    def config_frames(self, cfg: Evms3Config) -> list[Frame]:
        """Build the frames of IDs 32, 33, 34, 35 in that order (EncodeRangeError first)."""
        return [self._frame(CONFIG1 + i, p) for i, p in enumerate(_config_payloads(cfg))]

    def report_frames(self, cfg: Evms3Config, cells_per_module: Sequence[int]) -> list[Frame]:
        """Build the EVMS's answer to ID 51: IDs 52..55 (config) and 56 (cell numbers)."""
        frames = [Frame(CORE_SEND_CONFIG1 + i, bytes(p), self.is_extended_id)
                  for i, p in enumerate(_config_payloads(cfg))]
        cells = self.encode(BmsCellNumbers(tuple(cells_per_module)))
        return frames + [Frame(CORE_SEND_CELL_NUMS, cells.data, self.is_extended_id)]

    def encode(self, msg: Any) -> Frame:
        """Reading/command -> Frame; EncodeRangeError names the field and allowed range."""
        if isinstance(msg, Evms3Status):
            return self._encode_status(msg)
        if isinstance(msg, SetState):
            return self._frame(SET_STATE, bytes([1 if msg.setup else 0]))
        if isinstance(msg, Evms3ConfigPart):
            cfg = Evms3Config.from_mapping({**_CONFIG_FILLER, **msg.values})
            return self.config_frames(cfg)[msg.part - 1]
        if isinstance(msg, BmsCellNumbers):
            cells = check_config_value('cells_per_module', msg.cells_per_module)
            return self._frame(CELL_NUMBERS, bytes(
                cells[2 * n] | cells[2 * n + 1] << 4 for n in range(8)))
        if isinstance(msg, AcknowledgeError):
            _check_int('error', msg.error, 0, 16)
            return self._frame(ACK_ERROR, bytes([int(msg.error)]))
        if isinstance(msg, ResetSoc):
            return self._frame(RESET_SOC, b'')
        if isinstance(msg, RequestConfig):
            return Frame(CORE_REQUEST_CONFIG, b'', self.is_extended_id)
        if isinstance(msg, PowerOff):
            return self._frame(POWER_OFF, b'')
        if isinstance(msg, ZeroCurrentSensor):
            return self._frame(ZERO_CURRENT, b'')
        if isinstance(msg, BatteryCurrent):
            check_range('current_a', msg.current_a, -8388.608, 8388.607, 0.001, 'A')
            raw = int(round(msg.current_a * 1000)) + CURRENT_OFFSET_MA
            return self._frame(BATTERY_CURRENT, raw.to_bytes(3, 'big'))
        if isinstance(msg, (Bms12Request, Bms12Cells, Bms12Temperatures)):
            return self._encode_bms12(msg)
        if isinstance(msg, (ChargerCommand, ChargerStatus)):
            return self.chargers.encode(msg)
        raise TypeError(f'cannot encode {type(msg).__name__} as an EVMS3 frame')

    def _encode_status(self, msg: Evms3Status) -> Frame:
        _check_int('state', msg.state, 0, 5)
        _check_int('error', msg.error, 0, 16)
        check_range('amp_hours_ah', msg.amp_hours_ah, 0, 6553.5, 0.1, 'Ah')
        check_range('pack_voltage_v', msg.pack_voltage_v, 0, 6553.5, 0.1, 'V')
        check_range('aux_voltage_v', msg.aux_voltage_v, 0, 25.5, 0.1, 'V')
        iso = (101 if msg.isolation_pct is None
               else _check_int('isolation_pct', msg.isolation_pct, 0, 100))
        temp = 0 if msg.temperature_c is None else 40 + _check_int(
            'temperature_c', msg.temperature_c, -39, 215)
        ah, volts = round(msg.amp_hours_ah * 10), round(msg.pack_voltage_v * 10)
        return self._frame(STATUS, bytes([
            int(msg.state) | int(msg.error) << 3, ah >> 8, ah & 0xFF, volts >> 8, volts & 0xFF,
            round(msg.aux_voltage_v * 10), iso | (0x80 if msg.headlights else 0), temp]))

    def _encode_bms12(self, msg: Any) -> Frame:
        module = _check_int('module', msg.module, 0, BMS12_MAX_MODULES - 1)
        base = self.bms12_base + 10 * module
        if isinstance(msg, Bms12Request):
            mv = (0 if msg.balance_mv is None
                  else _check_int('balance_mv', msg.balance_mv, 1, 65535))
            return Frame(base, mv.to_bytes(2, 'big'), self.is_extended_id)
        if isinstance(msg, Bms12Temperatures):
            if len(msg.temperatures_c) != 2:
                raise EncodeRangeError('temperatures_c', msg.temperatures_c, '2 values')
            raw = [40 + _check_int(f'temperatures_c[{i}]', t, -40, 215)
                   for i, t in enumerate(msg.temperatures_c)]
            return Frame(base + 4, bytes(raw + [0] * 6), self.is_extended_id)
        if msg.first_cell not in (0, 4, 8):
            raise EncodeRangeError('first_cell', msg.first_cell, '0, 4 or 8')
        if len(msg.voltages_v) != 4:
            raise EncodeRangeError('voltages_v', msg.voltages_v, '4 values')
        data = bytearray()
        for i, volts in enumerate(msg.voltages_v):
            check_range(f'voltages_v[{i}]', volts, 0, 65.535, 0.001, 'V')
            data += int(round(volts * 1000)).to_bytes(2, 'big')
        return Frame(base + 1 + msg.first_cell // 4, bytes(data), self.is_extended_id)


def _check_int(name: str, value: Any, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or (isinstance(value, float) and not math.isfinite(value)):
        raise EncodeRangeError(name, value, f'an integer {low}..{high}')
    check_range(name, value, low, high, 1)
    return int(round(value))


# Valid values to encode a single decoded part: the other parts' fields do not reach its frame.
_CONFIG_FILLER: dict[str, Any] = {
    f.name: (f.low if f.low is not None else f.choices[0] if f.choices else False)
    for f in CONFIG_FIELDS if f.name != 'cells_per_module'}
