"""
ZEVA EVMS3 configuration: the typed config, its wire layout (IDs 32..36) and the read-back.

The 32 setting bytes of IDs 32..35 and the cell counts of ID 36 (docs/protocols.md section 3), in
physical units with the ranges the firmware allows (``CONFIG_FIELDS``: the encoder refuses,
instead of clamping, any value the EVMS would silently limit). Settings whose vendor range
ends in an "off"/"never" value (``SENTINELS``) take that end value as a documented number:
warn/trip current 1210 A = off, EVMS temperature warning 151 = off, BMS minimum temperature
-40 = off, BMS maximum temperature 101 = off, sleep delay 6 = never sleep. An 800 V build
(Common.h ``PACK_VOLTAGE_MULTIPLIER`` 2) doubles full and charge voltages (``multiplier``).
ZEVA's open EVMS3 firmware (MIT, August 2021) also reports them: ID 51 asks, 52..55 answer
in the layout of 32..35 and 56 in the layout of 36 (``ConfigReport``, joined by
``ConfigReadback``). ``protocols.evms3`` builds and reads the frames and re-exports every
name here.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Callable, Iterable, Mapping, Sequence

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols.common import (
    ConfigField, EncodeRangeError, MalformedFrameError)
from ams_can_bridge.protocols.layout import check_value, Layout, LITTLE, Signal

BMS12_MAX_MODULES = 16
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
# Cells per BMS12 module: 0 (absent) or 4..12 (the firmware holds 12 cells a module; the
# Monitor offers 4..12). The 4-bit nibble of ID 36 could carry 13..15: refused.
CELLS_MIN, CELLS_MAX = 4, 12
# Physical value of each setting whose raw range ends in "off"/"never" (EVMS3 firmware:
# CURRENT_WARNING/CURRENT_TRIP < 121, OVER_TEMP != 151, BMS_MIN_TEMP > 0, BMS_MAX_TEMP < 141,
# CAN_POWER_DOWN_DELAY != 6), and the word shown for it.
SENTINELS: dict[str, tuple[int, str]] = {
    'warn_current_a': (1210, 'off'), 'trip_current_a': (1210, 'off'),
    'temp_warning_c': (151, 'off'), 'bms_min_temp_c': (-40, 'off'),
    'bms_max_temp_c': (101, 'off'), 'sleep_delay_min': (6, 'never'),
}
VOLTAGE_MULTIPLIERS = (1, 2)  # Common.h PACK_VOLTAGE_MULTIPLIER: 1 (up to ~400 V) or 2 (800 V)
_SCALED = ('full_voltage_v', 'max_charge_voltage_v', 'alt_charge_voltage_v')


def sentinel_text(name: str, value: Any) -> str | None:
    """Return 'off'/'never' when value is the sentinel of setting name, else None."""
    sentinel = SENTINELS.get(name)
    if sentinel is None or isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return sentinel[1] if value == sentinel[0] else None


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
    reverse_current_display: bool  # setting 30, ID 35 byte 6 (shown by the ZEVA Monitor)
    night_brightness: int  # setting 31, ID 35 byte 7: 0..10 (x 10 % on the Monitor)

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
        # every name but balance_v is set (checked above)
        return cls(**{n: values.get(n) for n in names})  # type: ignore[arg-type]


@dataclass(frozen=True)
class Evms3ConfigPart:
    """One decoded configuration packet: part 1..4 (IDs 32..35) and its values by name."""

    part: int
    values: Mapping[str, Any] = field(default_factory=dict)


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
        off = [f'{name} {sentinel_text(name, getattr(cfg, name))}' for name in SENTINELS
               if sentinel_text(name, getattr(cfg, name))]
        return (f'{cfg.pack_capacity_ah} Ah, full {cfg.full_voltage_v} V, cells '
                f'{cfg.bms_min_cell_v:.2f}..{cfg.bms_max_cell_v:.2f} V, balance {balance}, '
                f'charge {cfg.max_charge_voltage_v} V {cfg.max_charge_current_a} A, '
                f'{len(modules)} BMS12 module(s) with {sum(modules)} cells'
                + (', ' + ', '.join(off) if off else ''))


# --- configuration table ----------------------------------------------------------------------
# The setting slots of IDs 32..35 (byte 8 * packet + byte), one table format shared with the
# BMS16 standard form (protocols.bms16_std), which gives several slots other meanings.
# Linear slots: (name, type, slot, scale, offset, raw low, raw high, unit, what).
SlotRow = tuple[str, type, int, float, float, int, int, str, str]
_LINEAR: tuple[SlotRow, ...] = (
    ('pack_capacity_ah', int, 0, 5, 0, 1, 250, 'Ah', 'pack capacity'),
    ('soc_warning_pct', int, 1, 1, 0, 0, 99, '%', 'state of charge warning level'),
    ('full_voltage_v', int, 2, 2, 0, 5, 251, 'V', 'pack voltage that counts as full'),
    ('warn_current_a', int, 3, 10, 0, 1, 121, 'A', 'overcurrent warning threshold'),
    ('trip_current_a', int, 4, 10, 0, 1, 121, 'A', 'overcurrent shutdown threshold'),
    ('temp_warning_c', int, 5, 1, 0, 0, 151, 'degC', 'EVMS temperature warning'),
    ('min_aux_voltage_v', int, 6, 1, 0, 8, 16, 'V', 'minimum 12 V (aux) voltage'),
    ('min_isolation_pct', int, 7, 1, 0, 0, 99, '%', 'minimum isolation integrity'),
    ('tacho_ppr', int, 8, 1, 0, 1, 6, '', 'tachometer pulses per revolution'),
    ('fuel_gauge_full_pct', int, 9, 1, 0, 0, 100, '%', 'fuel gauge output when full'),
    ('fuel_gauge_empty_pct', int, 10, 1, 0, 0, 100, '%', 'fuel gauge output when empty'),
    ('temp_gauge_hot_pct', int, 11, 1, 0, 0, 100, '%', 'temperature gauge output hot'),
    ('temp_gauge_cold_pct', int, 12, 1, 0, 0, 100, '%', 'temperature gauge output cold'),
    ('bms_min_cell_v', float, 13, 0.01, 1.5, 0, 250, 'V', 'BMS minimum cell voltage'),
    ('bms_max_cell_v', float, 14, 0.01, 2.0, 0, 250, 'V', 'BMS maximum cell voltage'),
    ('bms_hysteresis_v', float, 16, 0.01, 0, 0, 50, 'V', 'BMS hysteresis'),
    ('bms_min_temp_c', int, 17, 1, -40, 0, 141, 'degC', 'BMS minimum temperature'),
    ('bms_max_temp_c', int, 18, 1, -40, 0, 141, 'degC', 'BMS maximum temperature'),
    ('sleep_delay_min', int, 23, 1, 0, 1, 6, 'min', 'sleep delay'),
    ('mpi_function', int, 24, 1, 0, 0, 3, '', 'MPI function (EVMS3 manual order)'),
    ('mpo1_function', int, 25, 1, 0, 0, 6, '', 'MPO1 function (EVMS3 manual order)'),
    ('mpo2_function', int, 26, 1, 0, 0, 6, '', 'MPO2 function (EVMS3 manual order)'),
    ('parallel_strings', int, 27, 1, 0, 1, 20, '', 'parallel strings'),
    ('night_brightness', int, 31, 1, 0, 0, 10, '', 'Monitor night brightness, x 10 %'),
)
BALANCE_SLOT = 15
# 9-bit voltage (low byte + bit 7 of the current byte) and 7-bit current, slots 19..22
_CHARGE = (('max_charge_voltage_v', 'max_charge_current_a', 19),
           ('alt_charge_voltage_v', 'alt_charge_current_a', 21))
_BOOLS = (('enable_precharge', 28), ('stationary_mode', 29), ('reverse_current_display', 30))
BALANCE_MODES = ('static', 'dynamic', 'off')
# The name msg_defs/evms3.dbc gives each setting byte of _LINEAR and _BOOLS.
_DBC_NAMES = dict(zip(
    [row[0] for row in _LINEAR] + [name for name, _ in _BOOLS],
    ('PackCapacity', 'SocWarning', 'FullVoltage', 'WarnCurrent', 'TripCurrent',
     'EvmsTempWarning', 'MinAuxVoltage', 'MinIsolation', 'TachoPpr', 'FuelGaugeFull',
     'FuelGaugeEmpty', 'TempGaugeHot', 'TempGaugeCold', 'BmsMinVoltage', 'BmsMaxVoltage',
     'BmsHysteresis', 'BmsMinTemp', 'BmsMaxTemp', 'SleepDelay', 'MpiFunction', 'Mpo1Function',
     'Mpo2Function', 'ParallelStrings', 'NightBrightness', 'EnablePrecharge', 'StationaryMode',
     'ReverseCurrentDisplay')))


def config_layouts() -> list[Layout]:
    """
    Return the bits of IDs 32..35 and 36 in the table format of protocols/layout.py.

    Built from the tables the encoder and decoder here use (_LINEAR, _CHARGE, _BOOLS, the
    balance byte, the cell nibbles), so ``evms3.check_dbc`` proves them against the DBC.
    """
    def u(name: str, start: int, length: int = 8, scale: float = 1,
          offset: float = 0) -> Signal:
        return Signal(name, start, length, LITTLE, False, scale, offset)
    packets: list[list[Signal]] = [[] for _ in range(4)]
    for name, _, slot, scale, offset, *_ in _LINEAR:
        packets[slot // 8].append(u(_DBC_NAMES[name], 8 * (slot % 8), scale=scale,
                                    offset=offset))
    packets[1].append(u('BalanceVoltage', 56, scale=0.01, offset=2.0))
    for (_, _, slot), prefix in zip(_CHARGE, ('Max', 'Alt')):
        packets[2] += [u(f'{prefix}ChargeVoltageLow', 8 * (slot % 8)),
                       u(f'{prefix}ChargeCurrent', 8 * (slot % 8) + 8, 7),
                       u(f'{prefix}ChargeVoltageBit8', 8 * (slot % 8) + 15, 1, 256)]
    packets[3] += [u(_DBC_NAMES[name], 8 * (slot % 8)) for name, slot in _BOOLS]
    cells = [u(f'Module{m}Cells', 4 * m, 4) for m in range(BMS12_MAX_MODULES)]
    return [Layout(f'EVMS3_Config{k + 1}', 8, tuple(signals))
            for k, signals in enumerate(packets)] + [Layout('EVMS3_BmsCellNumbers', 8,
                                                            tuple(cells))]


# --- the slot codec, shared with protocols.bms16_std -------------------------------------------
def _phys(typ: type, scale: float, offset: float, raw: int) -> float:
    return int(raw * scale + offset) if typ is int else round(raw * scale + offset, 6)


def slot_field(row: SlotRow) -> ConfigField:
    """Return the ConfigField of a linear slot: its physical range, step and description."""
    name, typ, _, scale, offset, rlo, rhi, unit, what = row
    low, high = _phys(typ, scale, offset, rlo), _phys(typ, scale, offset, rhi)
    return ConfigField(name, typ, low, high, scale, unit,
                       f'{what} ({low:g}..{high:g} {unit})'.replace(' )', ')'))


BALANCE_FIELDS = (
    ConfigField('balance_v', float, 2.0, 4.5, 0.01, 'V',
                'static balance voltage (2.00..4.50 V), used only when balance_mode is static'),
    ConfigField('balance_mode', str, description='balancing: static (at balance_v), dynamic '
                'or off', choices=BALANCE_MODES))


def check_field(spec: ConfigField | None, name: str, value: Any,
                known: Iterable[str]) -> Any:
    """Validate a bool, choice or number setting; return it normalized (EncodeRangeError)."""
    if spec is None:
        raise EncodeRangeError(name, value, 'one of ' + ', '.join(known))
    if spec.type is bool:
        if isinstance(value, bool) or (isinstance(value, int) and value in (0, 1)):
            return bool(value)
        raise EncodeRangeError(name, value, 'true or false')
    if spec.type is str:
        if value not in spec.choices:
            raise EncodeRangeError(name, value, 'one of ' + ', '.join(spec.choices))
        return value
    number = check_value(name, value, spec.low, spec.high,  # type: ignore[arg-type]  # a range
                         spec.step, spec.unit)
    return int(round(number)) if spec.type is int else round(float(number), 6)


def pack_slots(rows: Iterable[SlotRow], slots: bytearray, values: Any,
               check: Callable[[str, Any], Any], multiplier: int = 1,
               check_unused_balance: bool = False) -> None:
    """Write the linear slots and then the balance byte of values (checked) into slots."""
    for name, _, slot, scale, offset, *_ in rows:
        value = check(name, getattr(values, name))
        slots[slot] = round((value - offset) / (scale * (multiplier if name in _SCALED
                                                         else 1)))
    mode = check('balance_mode', values.balance_mode)
    if mode == 'static' or (check_unused_balance and values.balance_v is not None):
        balance = check('balance_v', values.balance_v)
    slots[BALANCE_SLOT] = (BALANCE_DYNAMIC if mode == 'dynamic' else BALANCE_OFF
                           if mode == 'off' else round((balance - 2.0) / 0.01))


def unpack_slots(rows: Iterable[SlotRow], data: bytes, first: int,
                 fail: Callable[[str], Exception], multiplier: int = 1) -> dict[str, Any]:
    """Read the linear slots (and the balance byte) in data, slot first..; fail(why) if bad."""
    values: dict[str, Any] = {}
    for name, typ, slot, scale, offset, rlo, rhi, _, _ in rows:
        if first <= slot < first + len(data):
            raw = data[slot - first]
            if not rlo <= raw <= rhi:
                raise fail(f'{name} raw {raw} outside {rlo}..{rhi}')
            values[name] = _phys(typ, scale * (multiplier if name in _SCALED else 1),
                                 offset, raw)
    if first <= BALANCE_SLOT < first + len(data):
        raw = data[BALANCE_SLOT - first]
        if raw > BALANCE_OFF:
            raise fail(f'balance voltage raw {raw} outside 0..252')
        values['balance_mode'] = ('dynamic' if raw == BALANCE_DYNAMIC else
                                  'off' if raw == BALANCE_OFF else 'static')
        values['balance_v'] = round(2.0 + raw * 0.01, 2) if raw <= 250 else None
    return values


def _build_fields() -> tuple[ConfigField, ...]:
    by_name = {f.name: f for f in BALANCE_FIELDS}
    for row in _LINEAR:
        spec = slot_field(row)
        if row[0] in SENTINELS:
            value, word = SENTINELS[row[0]]
            spec = replace(spec, description=spec.description[:-1] + f'; {value} = {word})')
        if row[0] in _SCALED:  # declared wide enough for both builds; the device checks its own
            spec = replace(spec, high=_phys(row[1], row[3] * 2, row[4], row[6]),
                           description=spec.description[:-1] + '; x 2 with voltage_multiplier 2)')
        by_name[row[0]] = spec
    for volt, amp, _ in _CHARGE:
        kind = volt.split('_')[0]
        by_name[volt] = ConfigField(volt, int, 0, 1022, 1, 'V', f'{kind} charge voltage '
                                    '(0..511 V; x 2 with voltage_multiplier 2)')
        by_name[amp] = ConfigField(amp, int, 0, 127, 1, 'A', f'{kind} charge current (0..127 A)')
    by_name['enable_precharge'] = ConfigField('enable_precharge', bool,
                                              description='enable the precharge sequence')
    by_name['stationary_mode'] = ConfigField(
        'stationary_mode', bool, description='stationary (non-vehicle) mode: a low cell opens '
        'the main contactor, a high cell disables charging')
    by_name['reverse_current_display'] = ConfigField(
        'reverse_current_display', bool, description='ZEVA Monitor shows the current reversed')
    ordered = [by_name[f.name] for f in fields(Evms3Config)]
    ordered.append(ConfigField('cells_per_module', 'int[]', 0, CELLS_MAX, 1, '',
                               'cells on each of the 16 BMS12 modules (0 or 4..12), ID 36',
                               length=BMS12_MAX_MODULES))
    return tuple(ordered)


CONFIG_FIELDS: tuple[ConfigField, ...] = _build_fields()
_FIELD_BY_NAME = {f.name: f for f in CONFIG_FIELDS}


def check_config_value(name: str, value: Any, multiplier: int = 1) -> Any:
    """
    Validate one configuration value; return it normalized (int/float/bool/str/tuple).

    Raises EncodeRangeError naming the field, the value and what is allowed. Numbers may be
    written as int or float (3 and 3.0 are the same); nothing is clamped. ``multiplier``
    is the EVMS build's PACK_VOLTAGE_MULTIPLIER (1 or 2): full and charge voltages scale.
    """
    spec = _FIELD_BY_NAME.get(name)
    if spec is not None and spec.type == 'int[]':
        allowed = f'{spec.length} integers, each 0 or {CELLS_MIN}..{CELLS_MAX}'
        if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) \
                or len(value) != spec.length:
            raise EncodeRangeError(name, value, allowed)
        cells = tuple(int(check_value(f'{name}[{i}]', v, 0, CELLS_MAX, 1))
                      for i, v in enumerate(value))
        for i, n in enumerate(cells):
            if 0 < n < CELLS_MIN:
                raise EncodeRangeError(f'{name}[{i}]', n, f'0 or {CELLS_MIN}..{CELLS_MAX}')
        return cells
    if spec is not None and name in _SCALED:
        spec = _scaled(spec, multiplier)
    return check_field(spec, name, value, _FIELD_BY_NAME)


def _scaled(spec: ConfigField, multiplier: int) -> ConfigField:
    """Return the range of a full/charge voltage on a build with this multiplier."""
    if multiplier not in VOLTAGE_MULTIPLIERS:
        raise ConfigError(f'voltage multiplier {multiplier!r}: allowed 1 or 2')
    if spec.name == 'full_voltage_v':
        low, high, step = 10 * multiplier, 502 * multiplier, 2 * multiplier
    else:
        low, high, step = 0, 511 * multiplier, multiplier
    return ConfigField(spec.name, spec.type, low, high, step, spec.unit)


def config_payloads(cfg: Evms3Config, multiplier: int = 1) -> list[bytearray]:
    """Return the payloads of IDs 32..35 (EncodeRangeError names the first bad value)."""
    def check(name: str, value: Any) -> Any:
        return check_config_value(name, value, multiplier)
    slots = bytearray(32)
    pack_slots(_LINEAR, slots, cfg, check, multiplier, check_unused_balance=True)
    for volt, amp, slot in _CHARGE:
        v = check(volt, getattr(cfg, volt)) // multiplier
        slots[slot] = v & 0xFF
        slots[slot + 1] = check_config_value(amp, getattr(cfg, amp)) | (v >> 8) << 7
    for name, slot in _BOOLS:
        slots[slot] = int(check_config_value(name, getattr(cfg, name)))
    return [slots[8 * k:8 * k + 8] for k in range(4)]


def decode_config_packet(packet: int, aid: int, data: bytes,
                         multiplier: int = 1) -> Evms3ConfigPart:
    """Decode packet 0..3 (the layout of 32..35); MalformedFrameError for a raw value."""
    def fail(why: str) -> Exception:
        return MalformedFrameError(aid, data, why)
    values = unpack_slots(_LINEAR, data, 8 * packet, fail, multiplier)
    for volt, amp, slot in _CHARGE:
        if slot // 8 == packet:
            byte = slot % 8
            values[volt] = (data[byte] | (data[byte + 1] >> 7) << 8) * multiplier
            values[amp] = data[byte + 1] & 0x7F
    for name, slot in _BOOLS:
        if slot // 8 == packet:
            if data[slot % 8] > 1:
                raise fail(f'{name} raw {data[slot % 8]}, expected 0 or 1')
            values[name] = bool(data[slot % 8])
    return Evms3ConfigPart(packet + 1, values)


# Valid values to encode a single decoded part: the other parts' fields do not reach its frame.
CONFIG_FILLER: dict[str, Any] = {
    f.name: (f.low if f.low is not None else f.choices[0] if f.choices else False)
    for f in CONFIG_FIELDS if f.name != 'cells_per_module'}
