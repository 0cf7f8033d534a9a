# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA EVMS3 configuration: the typed config, its frames (IDs 32..36) and the read-back 51..56.

doc/protocols.md 3.4..3.6 hold the settings, ranges, off/never ends, the 800 V multiplier and
the read-back. The settings are layout rows (protocols/settings.py); this module adds the
balance byte, the 9-bit charge voltages and the cell nibbles.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Callable, Iterable, Mapping, Sequence

from ams_can_bridge.errors import ConfigError, EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.bms12 import BMS12_MAX_MODULES
from ams_can_bridge.protocols.common import check_dlc, ConfigField
from ams_can_bridge.protocols.layout import check_value, Layout, LITTLE, Signal
from ams_can_bridge.protocols.settings import setting, Settings

BALANCE_DYNAMIC = 251
BALANCE_OFF = 252
# Read-back: fixed IDs, not moved by base_id (doc/protocols.md 3.4)
CORE_REQUEST_CONFIG = 51
CORE_SEND_CONFIG1, CORE_SEND_CONFIG2, CORE_SEND_CONFIG3, CORE_SEND_CONFIG4 = range(52, 56)
CORE_SEND_CELL_NUMS = 56
READBACK_IDS = range(CORE_SEND_CONFIG1, CORE_SEND_CELL_NUMS + 1)
# also a ZEVA motor controller's settings IDs (Common.h MC_RECEIVE/SEND_SETTINGS_ID)
SHARED_READBACK_IDS = frozenset({CORE_SEND_CONFIG1, CORE_SEND_CONFIG2})
READBACK_NAMES = {52: 'config 1', 53: 'config 2', 54: 'config 3', 55: 'config 4',
                  56: 'cell numbers'}
CELLS_MIN, CELLS_MAX = 4, 12  # cells per BMS12 module, or 0 (doc/protocols.md 3.5)


def sentinel_text(name: str, value: Any) -> str | None:
    """Return 'off'/'never' when value is the sentinel of setting name, else None."""
    sentinel = SENTINELS.get(name)
    if sentinel is None or isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return sentinel[1] if value == sentinel[0] else None


@dataclass(frozen=True)
class Evms3Settings:
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
    def from_parts(cls, parts: Iterable[Evms3ConfigPart | ConfigReport]) -> Evms3Settings:
        """Join the four decoded packets or reports (any order) into one configuration."""
        return cls(**{name: value for part in parts for name, value in part.values.items()})

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> 'Evms3Settings':
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


@dataclass(frozen=True, slots=True)
class BmsCellNumbers:
    """ID 36: cells per BMS12 module, 16 values (0 or 4..12 to send; 4 bits on the wire)."""

    cells_per_module: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class OtherTraffic:
    """A frame on an ID the EVMS3 shares (52, 53) that carries no EVMS3 state: ignored."""

    arbitration_id: int
    what: str


@dataclass(frozen=True)
class ConfigReport:
    """IDs 52..56: one packet of the configuration the EVMS reports (its answer to 51)."""

    arbitration_id: int  # 52..55: the layout of 32..35; 56: the layout of 36
    values: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ConfigReadback:
    """A whole reported configuration (52..56 joined), or what was missing from it."""

    config: Evms3Settings | None
    cells_per_module: tuple[int, ...] | None
    missing: tuple[int, ...] = ()  # IDs of 52..56 not received

    @classmethod
    def join(cls, reports: Iterable[ConfigReport]) -> 'ConfigReadback':
        """Join the packets of one answer (any order); missing IDs named, nothing guessed."""
        by_id = {r.arbitration_id: r for r in reports}
        missing = tuple(i for i in READBACK_IDS if i not in by_id)
        if missing:
            return cls(None, None, missing)
        cells = by_id.pop(CORE_SEND_CELL_NUMS).values['cells_per_module']
        return cls(Evms3Settings.from_parts(by_id.values()), tuple(cells))

    def parameter_values(self) -> dict[str, Any]:
        """Every configuration field read, physical units (balance_v only when static)."""
        if self.config is None or self.cells_per_module is None:
            return {}
        values = {f.name: getattr(self.config, f.name) for f in fields(Evms3Settings)}
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
        off = [f'{name} {word}' for name, (value, word) in SENTINELS.items()
               if getattr(cfg, name) == value]
        return (f'{cfg.pack_capacity_ah} Ah, full {cfg.full_voltage_v} V, cells '
                f'{cfg.bms_min_cell_v:.2f}..{cfg.bms_max_cell_v:.2f} V, balance {balance}, '
                f'charge {cfg.max_charge_voltage_v} V {cfg.max_charge_current_a} A, '
                f'{len(modules)} BMS12 module(s) with {sum(modules)} cells'
                + (', ' + ', '.join(off) if off else ''))


# --- the balance byte, shared with protocols.bms16_std ----------------------------------------
# Slot 15: 2.00..4.50 V (raw 0..250), 251 dynamic, 252 off: one byte for two settings.
BALANCE_ROW = Signal('BalanceVoltage', 56, 8, LITTLE, scale=0.01, offset=2.0)
BALANCE_MODES = ('static', 'dynamic', 'off')
BALANCE_FIELDS = (
    ConfigField('balance_v', float, 2.0, 4.5, 0.01, 'V',
                'static balance voltage (2.00..4.50 V), used only when balance_mode is static'),
    ConfigField('balance_mode', str, description='balancing: static (at balance_v), dynamic '
                'or off', choices=BALANCE_MODES))
BALANCE_NAMES = ('balance_v', 'balance_mode')


def check_setting(settings: Settings, name: str, value: Any) -> Any:
    """Validate one value of settings or of the balance byte; return it normalized."""
    return check_balance(name, value) if name in BALANCE_NAMES else settings.check(name, value)


def check_balance(name: str, value: Any) -> Any:
    """Validate balance_mode (a choice) or balance_v (a voltage); EncodeRangeError if not."""
    if name == 'balance_mode':
        if value not in BALANCE_MODES:
            raise EncodeRangeError(name, value, 'one of ' + ', '.join(BALANCE_MODES))
        return value
    return round(float(check_value(name, value, 2.0, 4.5, 0.01, 'V')), 6)


def balance_byte(mode: Any, volts: Any, check_unused: bool = False) -> int:
    """Return slot 15 of a balance mode and voltage (checked; the voltage only if static)."""
    mode = check_balance('balance_mode', mode)
    if mode == 'static' or (check_unused and volts is not None):
        volts = check_balance('balance_v', volts)
    return (BALANCE_DYNAMIC if mode == 'dynamic' else BALANCE_OFF if mode == 'off'
            else round((volts - 2.0) / 0.01))


def balance_values(raw: int, fail: Callable[[str], Exception]) -> dict[str, Any]:
    """Return balance_mode and balance_v (None unless static) of slot 15; fail(why) if bad."""
    if raw > BALANCE_OFF:
        raise fail(f'balance voltage raw {raw} outside 0..252')
    return {'balance_mode': ('dynamic' if raw == BALANCE_DYNAMIC else
                             'off' if raw == BALANCE_OFF else 'static'),
            'balance_v': round(2.0 + raw * 0.01, 2) if raw <= 250 else None}


# --- the configuration table ----------------------------------------------------------------
# Common.h settings 0..31 in IDs 32..35 and the cell nibbles of ID 36, with the names of
# msg_defs/evms3.dbc (``evms3.check_dbc``) and the ranges of minimums[] / maximums[].
_CONFIG1 = Layout('EVMS3_Config1', 8, (
    setting('PackCapacity', 0, 'pack_capacity_ah', 5, 1250, 'Ah', 'pack capacity', scale=5),
    setting('SocWarning', 1, 'soc_warning_pct', 0, 99, '%', 'state of charge warning level'),
    setting('FullVoltage', 2, 'full_voltage_v', 10, 502, 'V',
            'pack voltage that counts as full', scale=2),
    setting('WarnCurrent', 3, 'warn_current_a', 10, 1210, 'A', 'overcurrent warning threshold',
            scale=10, sentinel=(1210, 'off')),
    setting('TripCurrent', 4, 'trip_current_a', 10, 1210, 'A',
            'overcurrent shutdown threshold', scale=10, sentinel=(1210, 'off')),
    setting('EvmsTempWarning', 5, 'temp_warning_c', 0, 151, 'degC', 'EVMS temperature warning',
            sentinel=(151, 'off')),
    setting('MinAuxVoltage', 6, 'min_aux_voltage_v', 8, 16, 'V', 'minimum 12 V (aux) voltage'),
    setting('MinIsolation', 7, 'min_isolation_pct', 0, 99, '%', 'minimum isolation integrity')))
_CONFIG2 = Layout('EVMS3_Config2', 8, (
    setting('TachoPpr', 0, 'tacho_ppr', 1, 6, '', 'tachometer pulses per revolution'),
    setting('FuelGaugeFull', 1, 'fuel_gauge_full_pct', 0, 100, '%', 'fuel gauge output when full'),
    setting('FuelGaugeEmpty', 2, 'fuel_gauge_empty_pct', 0, 100, '%',
            'fuel gauge output when empty'),
    setting('TempGaugeHot', 3, 'temp_gauge_hot_pct', 0, 100, '%', 'temperature gauge output hot'),
    setting('TempGaugeCold', 4, 'temp_gauge_cold_pct', 0, 100, '%',
            'temperature gauge output cold'),
    setting('BmsMinVoltage', 5, 'bms_min_cell_v', 1.5, 4.0, 'V', 'BMS minimum cell voltage',
            float, 0.01, 1.5),
    setting('BmsMaxVoltage', 6, 'bms_max_cell_v', 2.0, 4.5, 'V', 'BMS maximum cell voltage',
            float, 0.01, 2.0),
    BALANCE_ROW))
_CONFIG3 = Layout('EVMS3_Config3', 8, (
    setting('BmsHysteresis', 0, 'bms_hysteresis_v', 0, 0.5, 'V', 'BMS hysteresis', float, 0.01),
    setting('BmsMinTemp', 1, 'bms_min_temp_c', -40, 101, 'degC', 'BMS minimum temperature',
            offset=-40, sentinel=(-40, 'off')),
    setting('BmsMaxTemp', 2, 'bms_max_temp_c', -40, 101, 'degC', 'BMS maximum temperature',
            offset=-40, sentinel=(101, 'off')),
    # charge voltages: 9 bits, the low byte and bit 7 of the current's byte (by hand below)
    Signal('MaxChargeVoltageLow', 24, 8, LITTLE),
    setting('MaxChargeCurrent', 4, 'max_charge_current_a', 0, 127, 'A', 'max charge current',
            length=7),
    Signal('MaxChargeVoltageBit8', 39, 1, LITTLE, scale=256),
    Signal('AltChargeVoltageLow', 40, 8, LITTLE),
    setting('AltChargeCurrent', 6, 'alt_charge_current_a', 0, 127, 'A', 'alt charge current',
            length=7),
    Signal('AltChargeVoltageBit8', 55, 1, LITTLE, scale=256),
    setting('SleepDelay', 7, 'sleep_delay_min', 1, 6, 'min', 'sleep delay',
            sentinel=(6, 'never'))))
_CONFIG4 = Layout('EVMS3_Config4', 8, (
    setting('MpiFunction', 0, 'mpi_function', 0, 3, '', 'MPI function (EVMS3 manual order)'),
    setting('Mpo1Function', 1, 'mpo1_function', 0, 6, '', 'MPO1 function (EVMS3 manual order)'),
    setting('Mpo2Function', 2, 'mpo2_function', 0, 6, '', 'MPO2 function (EVMS3 manual order)'),
    setting('ParallelStrings', 3, 'parallel_strings', 1, 20, '', 'parallel strings'),
    setting('EnablePrecharge', 4, 'enable_precharge', 0, 1, '', 'enable the precharge sequence',
            bool),
    setting('StationaryMode', 5, 'stationary_mode', 0, 1, '', 'stationary (non-vehicle) mode: '
            'a low cell opens the main contactor, a high cell disables charging', bool),
    setting('ReverseCurrentDisplay', 6, 'reverse_current_display', 0, 1, '',
            'ZEVA Monitor shows the current reversed', bool),
    setting('NightBrightness', 7, 'night_brightness', 0, 10, '',
            'Monitor night brightness, x 10 %')))
CELL_NUMBERS_LAYOUT = Layout('EVMS3_BmsCellNumbers', 8, tuple(
    Signal(f'Module{m}Cells', 4 * m, 4, LITTLE) for m in range(BMS12_MAX_MODULES)))
_D_CELL_NUMBERS: Callable[[bytes], tuple[int, ...]] = CELL_NUMBERS_LAYOUT.decoder()
_E_CELL_NUMBERS = CELL_NUMBERS_LAYOUT.encoder()
CONFIG_LAYOUTS = (_CONFIG1, _CONFIG2, _CONFIG3, _CONFIG4, CELL_NUMBERS_LAYOUT)
# By PACK_VOLTAGE_MULTIPLIER: an 800 V build counts the full voltage in 4 V steps.
_SETTINGS = {1: Settings(CONFIG_LAYOUTS[:4]), 2: Settings((_CONFIG1.replace(
    'FullVoltage', scale=4, low=20, high=1004), *CONFIG_LAYOUTS[1:4]))}
_CHARGE = ('max_charge_voltage_v', 'alt_charge_voltage_v')  # x multiplier as full voltage
_D_CHARGE = _CONFIG3.decoder('MaxChargeVoltageLow', 'MaxChargeVoltageBit8',
                             'AltChargeVoltageLow', 'AltChargeVoltageBit8')
SENTINELS: dict[str, tuple[float, str]] = _SETTINGS[1].sentinels()


_X2 = '; x 2 with voltage_multiplier 2)'


def _build_fields() -> tuple[ConfigField, ...]:
    """Return the fields in Evms3Settings's order: the rows', the balance and charge voltages."""
    by_name = {f.name: f for f in (*_SETTINGS[1].fields(), *BALANCE_FIELDS)}
    full = by_name['full_voltage_v']  # declared wide enough for both builds
    by_name[full.name] = replace(full, high=_SETTINGS[2].field(full.name).high,
                                 description=full.description[:-1] + _X2)
    for volt in _CHARGE:
        by_name[volt] = ConfigField(volt, int, 0, 1022, 1, 'V', volt.split('_')[0]
                                    + ' charge voltage (0..511 V' + _X2)
    return tuple(by_name[f.name] for f in fields(Evms3Settings)) + (ConfigField(
        'cells_per_module', 'int[]', 0, CELLS_MAX, 1, '',
        'cells on each of the 16 BMS12 modules (0 or 4..12), ID 36', length=BMS12_MAX_MODULES),)


CONFIG_FIELDS: tuple[ConfigField, ...] = _build_fields()


def check_config_value(name: str, value: Any, multiplier: int = 1) -> Any:
    """
    Validate one value; return it normalized, else EncodeRangeError (nothing is clamped).

    ``multiplier``: the build's PACK_VOLTAGE_MULTIPLIER (1 or 2) scales the full and charge
    voltages.
    """
    if multiplier not in (1, 2):  # Common.h PACK_VOLTAGE_MULTIPLIER
        raise ConfigError(f'voltage multiplier {multiplier!r}: allowed 1 or 2')
    if name == 'cells_per_module':
        allowed = f'{BMS12_MAX_MODULES} integers, each 0 or {CELLS_MIN}..{CELLS_MAX}'
        if isinstance(value, (str, bytes)) or not isinstance(value, Sequence) \
                or len(value) != BMS12_MAX_MODULES:
            raise EncodeRangeError(name, value, allowed)
        cells = tuple(int(check_value(f'{name}[{i}]', v, 0, CELLS_MAX, 1))
                      for i, v in enumerate(value))
        for i, n in enumerate(cells):
            if 0 < n < CELLS_MIN:
                raise EncodeRangeError(f'{name}[{i}]', n, f'0 or {CELLS_MIN}..{CELLS_MAX}')
        return cells
    if name in _CHARGE:
        return int(check_value(name, value, 0, 511 * multiplier, multiplier, 'V'))
    return check_setting(_SETTINGS[multiplier], name, value)


def config_payloads(cfg: Evms3Settings, multiplier: int = 1) -> list[bytes]:
    """Return the payloads of IDs 32..35 (EncodeRangeError names the first bad value)."""
    raws = {BALANCE_ROW.name: balance_byte(cfg.balance_mode, cfg.balance_v, True)}
    for volt, prefix in zip(_CHARGE, ('Max', 'Alt')):
        v = check_config_value(volt, getattr(cfg, volt), multiplier) // multiplier
        raws[f'{prefix}ChargeVoltageLow'], raws[f'{prefix}ChargeVoltageBit8'] = v & 0xFF, v >> 8
    return [_SETTINGS[multiplier].payload(k, cfg, raws) for k in range(4)]


def decode_config_packet(packet: int, aid: int, data: bytes,
                         multiplier: int = 1) -> Evms3ConfigPart:
    """Decode packet 0..3 (the layout of 32..35); MalformedFrameError for a raw value."""
    def fail(why: str) -> Exception:
        return MalformedFrameError(aid, data, why)
    check_dlc(aid, data, 8)  # ID 35 too: bytes 6-7 are settings 30-31 (Common.h)
    values = _SETTINGS[multiplier].decode(packet, data, fail)
    if packet == 1:
        values.update(balance_values(data[7], fail))
    if packet == 2:
        max_low, max_bit8, alt_low, alt_bit8 = _D_CHARGE(data)
        values['max_charge_voltage_v'] = (max_low + max_bit8) * multiplier
        values['alt_charge_voltage_v'] = (alt_low + alt_bit8) * multiplier
    return Evms3ConfigPart(packet + 1, values)


def decode_report(aid: int, data: bytes, multiplier: int = 1) -> ConfigReport | OtherTraffic:
    """Decode one packet of the EVMS's answer to ID 51 (52..55 config, 56 cell numbers)."""
    if aid == CORE_SEND_CELL_NUMS:
        return ConfigReport(aid, {'cells_per_module': decode_cell_numbers(aid, data)})
    # A Monitor's or motor controller's frame on 52/53 is normal traffic: only a frame that
    # reads as the EVMS3's packet counts, the rest is ignored.
    if aid in SHARED_READBACK_IDS and len(data) != 8:
        return OtherTraffic(aid, f'DLC {len(data)}: motor-controller settings traffic')
    try:
        part = decode_config_packet(aid - CORE_SEND_CONFIG1, aid, data, multiplier)
    except MalformedFrameError as exc:
        if aid not in SHARED_READBACK_IDS:
            raise
        return OtherTraffic(aid, f'not an EVMS3 configuration ({exc.reason})')
    return ConfigReport(aid, part.values)


def decode_cell_numbers(aid: int, data: bytes) -> tuple[int, ...]:
    """Decode ID 36 or 56: cells per module; MalformedFrameError for 1..3 or 13..15."""
    check_dlc(aid, data, 8)
    cells = _D_CELL_NUMBERS(data)
    for m, n in enumerate(cells):
        if 0 < n < CELLS_MIN or n > CELLS_MAX:  # 13..15 overrun the firmware's arrays
            raise MalformedFrameError(aid, data, f'module {m}: {n} cells (0 or '
                                      f'{CELLS_MIN}..{CELLS_MAX})')
    return cells


def cell_numbers_payload(cells_per_module: Sequence[int]) -> bytes:
    """Return the payload of ID 36 (and 56); EncodeRangeError names a bad module."""
    return _E_CELL_NUMBERS(*check_config_value('cells_per_module', cells_per_module))


# Valid values to encode a single decoded part: the other parts' fields do not reach its frame.
CONFIG_FILLER: dict[str, Any] = {
    f.name: (f.low if f.low is not None else f.choices[0] if f.choices else False)
    for f in CONFIG_FIELDS if f.name != 'cells_per_module'}
