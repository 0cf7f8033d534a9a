"""
Formula-Student AMS (accumulator management system) protocol: docs/protocols.md section 1.

Ten 11-bit messages at ``base_id + offset`` (default base 0x300). The field layout is
``msg_defs/ams.dbc``: frames are encoded through cantools, and decoded by hand on that layout
(the bus thread decodes every frame; cantools cost 4-13 us a frame), checked against the
installed DBC when the first codec is built and against cantools in the tests. The module
adds what a DBC cannot say (valid bank/group IDs, known enum values, DLC checks: a frame
padded beyond its layout up to 8 bytes is accepted, a shorter one is malformed; typed
readings) and checks every value before it is encoded, so a bad command fails loudly
instead of being clamped.
Readings are frozen dataclasses; enums carry the vendor's names.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Callable, Union

from ams_can_bridge.protocols.common import (
    check_range, EncodeRangeError, Frame, load_dbc, MalformedFrameError)

DEFAULT_BASE_ID = 0x300

# Offsets from the base ID (docs/protocols.md section 1 table).
STATUS = 0x000
CHARGER_STATUS = 0x001
CAR_STATUS = 0x005
CHARGER_COMMANDS = 0x010
CELL_VOLTAGES = 0x011
CELL_TEMPERATURES = 0x012
DISCHARGE_TEMPERATURES = 0x013
ERROR = 0x014
OVERRIDE_CHARGE_CURRENT = 0x050
OVERRIDE_BANK_COUNT = 0x051
OFFSETS = (STATUS, CHARGER_STATUS, CAR_STATUS, CHARGER_COMMANDS, CELL_VOLTAGES,
           CELL_TEMPERATURES, DISCHARGE_TEMPERATURES, ERROR, OVERRIDE_CHARGE_CURRENT,
           OVERRIDE_BANK_COUNT)

MAX_DLC = 8  # classic CAN: frames padded up to 8 bytes are accepted
MAX_BANKS = 5
CELLS_PER_GROUP = 7
CELL_GROUPS = 4
CELLS_PER_BANK = CELLS_PER_GROUP * CELL_GROUPS  # 28
TEMPS_PER_GROUP = 5
DISCHARGE_TEMPS_PER_GROUP = 7
TEMP_GROUPS = 2
TEMPS_PER_BANK = TEMPS_PER_GROUP * TEMP_GROUPS  # 10
DISCHARGE_TEMPS_PER_BANK = DISCHARGE_TEMPS_PER_GROUP * TEMP_GROUPS  # 14
CELL_VOLT_STEP = 0.02  # V per bit (cells and Volt_min)
CURRENT_STEP = 0.1  # A per bit (charger current, override charge current)


class AmsState(enum.IntEnum):
    """AMS controller state (status word bits 4..0)."""

    NOT_REPORTED = 0
    IDLE = 1
    SC_ENABLED = 2
    TS_ACTIVE = 3
    DRIVE = 4
    ERROR = 5
    INIT_CHARGING = 6
    PRECHARGING = 7
    CHARGING = 8
    CHARGE_ERROR = 9


class CarCommand(enum.IntEnum):
    """Command of the master in the car-status heartbeat (byte 0 bits 3..0)."""

    NO_COMMAND = 0
    ENABLE_SC = 1
    ENABLE_TS = 2
    ENABLE_DRIVE = 3
    ABORT = 4
    SET_BANK_COUNT = 5
    SYNC_TIME = 6


class AmsError(enum.IntEnum):
    """AMS error IDs (vendor names without ERROR_AMS_; AIR-/AIR+/PRE+ spelled out)."""

    CELL_VOLTAGE_LOW = 1
    CELL_VOLTAGE_HIGH = 2
    CELL_TEMP_LOW = 3
    CELL_TEMP_HIGH = 4
    LTC6813_COMM = 5
    SHUNT_COMM = 6
    UNABLE_TO_OPEN_SC = 7
    UNABLE_TO_CLOSE_SC = 8
    UNABLE_TO_OPEN_AIR_MINUS = 9
    UNABLE_TO_CLOSE_AIR_MINUS = 10
    UNABLE_TO_OPEN_AIR_PLUS = 11
    UNABLE_TO_CLOSE_AIR_PLUS = 12
    UNABLE_TO_OPEN_PRE_PLUS = 13
    UNABLE_TO_CLOSE_PRE_PLUS = 14
    PRE_TIMEOUT = 15
    UNEXPECTED_CHARGE_RATE = 16
    BANK_COUNT_MISMATCH = 17
    UNEXPECTED_TS_CURRENT = 18
    RELAY_FAILED = 19
    SC_BROKEN = 20
    UNFIT_CHARGE_VOLTAGE = 21
    MONITOR_ERROR = 22
    DISCHARGE_TEMP_TIMEOUT = 23


class ChargerStart(enum.IntEnum):
    """Start/stop field of the charger commands (byte 0 bits 1..0)."""

    NO_COMMAND = 0
    START = 1
    STOP = 2


@dataclass(frozen=True, slots=True)
class AmsStatusWord:
    """The 16-bit status word (relay bits 1 = closed; bank count as the AMS counted it)."""

    air_plus: bool = False
    air_minus: bool = False
    precharge: bool = False
    warn_volt: bool = False
    warn_temp: bool = False
    hvdc_interlock: bool = False
    imd_error: bool = False
    ams_error: bool = False
    bank_count: int = 0
    state: AmsState = AmsState.NOT_REPORTED


@dataclass(frozen=True, slots=True)
class AmsStatus:
    """AMS status for the car (base + 0x000), the AMS's primary frame."""

    status: AmsStatusWord
    volt_min_v: float
    temp_max_c: int
    soc_pct: int
    counter: int
    relay_error_air_minus: bool = False
    relay_error_air_plus: bool = False
    relay_error_precharge: bool = False


@dataclass(frozen=True, slots=True)
class AmsChargerStatus:
    """AMS status for the charger (base + 0x001)."""

    status: AmsStatusWord
    soc_pct: int
    charger_current_a: float
    charger_on: bool


@dataclass(frozen=True, slots=True)
class CarStatus:
    """Car-status heartbeat from the master (base + 0x005)."""

    command: CarCommand
    bank_count: int
    counter: int


@dataclass(frozen=True, slots=True)
class ChargerCommand:
    """Charger commands (base + 0x010)."""

    start: ChargerStart
    time_tick: int


@dataclass(frozen=True, slots=True)
class CellVoltages:
    """Seven cell voltages of one bank (1..5) and group (0..3), base + 0x011."""

    bank: int
    group: int
    voltages_v: tuple[float, ...]

    @property
    def first_cell(self) -> int:
        """Index (0-based) within the bank of the first voltage: group * 7."""
        return self.group * CELLS_PER_GROUP


@dataclass(frozen=True, slots=True)
class CellTemperatures:
    """Five cell temperatures of one bank (1..5) and group (0..1), base + 0x012."""

    bank: int
    group: int
    temperatures_c: tuple[int, ...]

    @property
    def first_sensor(self) -> int:
        """Index (0-based) within the bank of the first temperature: group * 5."""
        return self.group * TEMPS_PER_GROUP


@dataclass(frozen=True, slots=True)
class DischargeTemperatures:
    """Seven discharge temperatures of one bank (1..5) and group (0..1), base + 0x013."""

    bank: int
    group: int
    temperatures_c: tuple[int, ...]

    @property
    def first_sensor(self) -> int:
        """Index (0-based) within the bank of the first temperature: group * 7."""
        return self.group * DISCHARGE_TEMPS_PER_GROUP


@dataclass(frozen=True, slots=True)
class AmsErrorEvent:
    """An AMS error event (base + 0x014) with the AMS time tick."""

    error: AmsError
    time_tick: int


@dataclass(frozen=True, slots=True)
class OverrideChargeCurrent:
    """Override of the charge current (base + 0x050)."""

    current_a: float


@dataclass(frozen=True, slots=True)
class OverrideBankCount:
    """Override of the bank count (base + 0x051)."""

    bank_count: int


AmsMessage = Union[AmsStatus, AmsChargerStatus, CarStatus, ChargerCommand, CellVoltages,
                   CellTemperatures, DischargeTemperatures, AmsErrorEvent,
                   OverrideChargeCurrent, OverrideBankCount]

# Value -> enum member, so decoding is a dict lookup (None = unknown value = malformed).
_STATES = {int(m): m for m in AmsState}
_COMMANDS = {int(m): m for m in CarCommand}
_ERRORS = {int(m): m for m in AmsError}
_STARTS = {int(m): m for m in ChargerStart}

_STATUS_BITS = (('AIR_Plus', 'air_plus'), ('AIR_Minus', 'air_minus'),
                ('Precharge_Relay', 'precharge'), ('Warn_Volt', 'warn_volt'),
                ('Warn_Temp', 'warn_temp'), ('HVDC_Interlock', 'hvdc_interlock'),
                ('IMD_Error', 'imd_error'), ('AMS_Error', 'ams_error'))
_CELL_SIGNALS = tuple(f'Cell_Voltage_{k}' for k in range(1, CELLS_PER_GROUP + 1))
_TEMP_SIGNALS = tuple(f'Cell_Temperature_{k}' for k in range(1, TEMPS_PER_GROUP + 1))
_DISCHARGE_SIGNALS = tuple(
    f'Discharge_Temperature_{k}' for k in range(1, DISCHARGE_TEMPS_PER_GROUP + 1))

_DBC_NAMES = {
    STATUS: 'AMS_Status', CHARGER_STATUS: 'AMS_Status_Charger', CAR_STATUS: 'CAR_Status',
    CHARGER_COMMANDS: 'CHARGER_Commands', CELL_VOLTAGES: 'AMS_Cell_Voltages',
    CELL_TEMPERATURES: 'AMS_Cell_Temperatures',
    DISCHARGE_TEMPERATURES: 'AMS_Discharge_Temperatures', ERROR: 'AMS_Error',
    OVERRIDE_CHARGE_CURRENT: 'CHARGER_Override_Charge_Current',
    OVERRIDE_BANK_COUNT: 'CHARGER_Override_Bank_Count',
}


class _Bad(Exception):
    """Internal: a decoded value is impossible (becomes MalformedFrameError with the data)."""


# --- decoding: by hand, on the layout msg_defs/ams.dbc gives --------------------------------
# The bus thread decodes every AMS frame (about 60/s with 5 banks): cantools took 4-13 us a
# frame, these take about 1. The DBC stays the reference: _check_dbc() fails at the first
# codec if the installed DBC no longer has this layout, and test_protocol_ams.py compares
# every message with cantools on random frames. Layout per message: DLC and its signals as
# (name, start bit (DBC numbering), length, signed, scale); every one big-endian, offset 0.
_FLAG_SIGNALS = tuple((dbc, 7 - bit, 1, False, 1) for bit, (dbc, _) in enumerate(_STATUS_BITS))
_WORD_SIGNALS = _FLAG_SIGNALS + (('Bank_Count', 15, 3, False, 1), ('AMS_State', 12, 5, False, 1))
_BANK_GROUP = (('Bank_ID', 7, 3, False, 1), ('Group_ID', 2, 3, False, 1))
_LAYOUT: dict[int, tuple[int, tuple[tuple[str, int, int, bool, float], ...]]] = {
    STATUS: (7, _WORD_SIGNALS + (
        ('Volt_min', 23, 8, False, CELL_VOLT_STEP), ('Temp_max', 31, 8, False, 1),
        ('SOC', 39, 8, False, 1), ('Counter', 47, 8, False, 1),
        ('Relay_Error_AIR_Minus', 48, 1, False, 1), ('Relay_Error_AIR_Plus', 49, 1, False, 1),
        ('Relay_Error_Precharge', 50, 1, False, 1))),
    CHARGER_STATUS: (5, _WORD_SIGNALS + (
        ('SOC', 23, 8, False, 1), ('Charger_Current', 31, 8, False, CURRENT_STEP),
        ('Turn_On_Charger', 32, 1, False, 1))),
    CAR_STATUS: (2, (('CMD', 3, 4, False, 1), ('Bank_Count', 7, 4, False, 1),
                     ('Counter', 15, 8, False, 1))),
    CHARGER_COMMANDS: (3, (('Start', 1, 2, False, 1), ('Time_Tick', 15, 16, False, 1))),
    CELL_VOLTAGES: (8, _BANK_GROUP + tuple(
        (name, 15 + 8 * k, 8, False, CELL_VOLT_STEP) for k, name in enumerate(_CELL_SIGNALS))),
    CELL_TEMPERATURES: (6, _BANK_GROUP + tuple(
        (name, 15 + 8 * k, 8, True, 1) for k, name in enumerate(_TEMP_SIGNALS))),
    DISCHARGE_TEMPERATURES: (8, _BANK_GROUP + tuple(
        (name, 15 + 8 * k, 8, True, 1) for k, name in enumerate(_DISCHARGE_SIGNALS))),
    ERROR: (3, (('AMS_Error_ID', 7, 8, False, 1), ('AMS_Time_Tick', 15, 16, False, 1))),
    OVERRIDE_CHARGE_CURRENT: (1, (('Charge_Current', 7, 8, False, CURRENT_STEP),)),
    OVERRIDE_BANK_COUNT: (1, (('Bank_Count', 7, 8, False, 1),)),
}
# Scaled values of a byte, as cantools computes them (raw * scale + offset).
_VOLTS = tuple(raw * CELL_VOLT_STEP + 0 for raw in range(256))
_AMPS = tuple(raw * CURRENT_STEP + 0 for raw in range(256))
_SIGNED = tuple(raw - 256 if raw > 127 else raw for raw in range(256))
_volts = _VOLTS.__getitem__
_signed = _SIGNED.__getitem__


def _check_dbc() -> None:
    """Fail loudly if msg_defs/ams.dbc no longer has the layout the decoders hard-code."""
    db = load_dbc('ams')
    for offset, (length, signals) in _LAYOUT.items():
        msg = db.get_message_by_name(_DBC_NAMES[offset])
        got = (msg.length, sorted(
            (s.name, s.start, s.length, s.is_signed, s.scale, s.offset, s.byte_order,
             s.is_float) for s in msg.signals))
        want = (length, sorted(
            (name, start, bits, signed, scale, 0, 'big_endian', False)
            for name, start, bits, signed, scale in signals))
        if got != want:
            raise RuntimeError(f'msg_defs/ams.dbc {msg.name} does not match the AMS codec '
                               f'layout: {got}')


# Status words seen so far, by their raw 16-bit value: a car sends a handful of distinct words,
# and building a frozen dataclass costs more than decoding the rest of the frame.
_WORD_CACHE: dict[int, AmsStatusWord] = {}


def _status_word(data: bytes) -> AmsStatusWord:
    raw = data[0] << 8 | data[1]  # bytes or bytearray (python-can gives the latter)
    word = _WORD_CACHE.get(raw)
    if word is not None:
        return word
    state = _STATES.get(raw & 0x1F)
    if state is None:
        raise _Bad(f'unknown AMS state {raw & 0x1F} (known 0..9)')
    banks = raw >> 5 & 0x07
    if banks > MAX_BANKS:
        raise _Bad(f'status bank count {banks} (allowed 0..{MAX_BANKS})')
    flags = data[0]
    word = AmsStatusWord(bool(flags & 0x80), bool(flags & 0x40), bool(flags & 0x20),
                         bool(flags & 0x10), bool(flags & 0x08), bool(flags & 0x04),
                         bool(flags & 0x02), bool(flags & 0x01), banks, state)
    _WORD_CACHE[raw] = word  # bounded: at most 2**16 words
    return word


def _bank_group(data: bytes, groups: int) -> tuple[int, int]:
    bank, group = data[0] >> 5, data[0] & 0x07
    if not 1 <= bank <= MAX_BANKS:
        raise _Bad(f'bank ID {bank} (allowed 1..{MAX_BANKS})')
    if group >= groups:
        raise _Bad(f'group ID {group} (allowed 0..{groups - 1})')
    return bank, group


def _dec_status(data: bytes) -> AmsStatus:
    relays = data[6]
    return AmsStatus(_status_word(data), _VOLTS[data[2]], data[3], data[4], data[5],
                     bool(relays & 0x01), bool(relays & 0x02), bool(relays & 0x04))


def _dec_charger_status(data: bytes) -> AmsChargerStatus:
    return AmsChargerStatus(_status_word(data), data[2], _AMPS[data[3]], bool(data[4] & 0x01))


def _dec_car_status(data: bytes) -> CarStatus:
    command = _COMMANDS.get(data[0] & 0x0F)
    if command is None:
        raise _Bad(f'unknown car command {data[0] & 0x0F} (known 0..6)')
    banks = data[0] >> 4
    if not 1 <= banks <= MAX_BANKS:
        raise _Bad(f'car status bank count {banks} (allowed 1..{MAX_BANKS})')
    return CarStatus(command, banks, data[1])


def _dec_charger_commands(data: bytes) -> ChargerCommand:
    start = _STARTS.get(data[0] & 0x03)
    if start is None:
        raise _Bad(f'unknown charger start command {data[0] & 0x03} (known 0..2)')
    return ChargerCommand(start, data[1] << 8 | data[2])


def _dec_cells(data: bytes) -> CellVoltages:
    bank, group = _bank_group(data, CELL_GROUPS)
    return CellVoltages(bank, group, tuple(map(_volts, data[1:8])))


def _dec_temps(data: bytes) -> CellTemperatures:
    bank, group = _bank_group(data, TEMP_GROUPS)
    return CellTemperatures(bank, group, tuple(map(_signed, data[1:6])))


def _dec_discharge(data: bytes) -> DischargeTemperatures:
    bank, group = _bank_group(data, TEMP_GROUPS)
    return DischargeTemperatures(bank, group, tuple(map(_signed, data[1:8])))


def _dec_error(data: bytes) -> AmsErrorEvent:
    error = _ERRORS.get(data[0])
    if error is None:
        raise _Bad(f'unknown AMS error ID {data[0]} (known 1..23)')
    return AmsErrorEvent(error, data[1] << 8 | data[2])


def _dec_override_current(data: bytes) -> OverrideChargeCurrent:
    return OverrideChargeCurrent(_AMPS[data[0]])


def _dec_override_banks(data: bytes) -> OverrideBankCount:
    banks = data[0]
    if not 1 <= banks <= MAX_BANKS:
        raise _Bad(f'override bank count {banks} (allowed 1..{MAX_BANKS})')
    return OverrideBankCount(banks)


_DECODERS: dict[int, Callable[[bytes], Any]] = {
    STATUS: _dec_status, CHARGER_STATUS: _dec_charger_status, CAR_STATUS: _dec_car_status,
    CHARGER_COMMANDS: _dec_charger_commands, CELL_VOLTAGES: _dec_cells,
    CELL_TEMPERATURES: _dec_temps, DISCHARGE_TEMPERATURES: _dec_discharge, ERROR: _dec_error,
    OVERRIDE_CHARGE_CURRENT: _dec_override_current, OVERRIDE_BANK_COUNT: _dec_override_banks,
}


# --- encode-side checks ---------------------------------------------------------------------
def _num(field: str, value: Any, low: float, high: float, step: float | None = None,
         unit: str = '') -> float:
    """Check a number against its wire range and step; bool and non-numbers are refused."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        suffix = f' {unit}' if unit else ''
        raise EncodeRangeError(field, value, f'a number {low:g}..{high:g}{suffix}')
    # Float noise at the ends (255 * 0.02 = 5.1000000000000005, as decoded) is no overrange.
    eps = (step or 1.0) * 1e-9
    if high < value <= high + eps:
        value = high
    elif low - eps <= value < low:
        value = low
    check_range(field, value, low, high, step, unit)
    return value


def _int(field: str, value: Any, low: int, high: int) -> int:
    # 3.0 is accepted (YAML spells numbers either way); 2.5 is not.
    if isinstance(value, float) and value == value and not value.is_integer():
        raise EncodeRangeError(field, value, f'{low}..{high}, a whole number')
    return int(_num(field, value, low, high))


def _flag(field: str, value: Any) -> int:
    if value not in (0, 1) or not isinstance(value, (bool, int)):
        raise EncodeRangeError(field, value, 'True/False (or 0/1)')
    return int(value)


def _member(field: str, value: Any, enum_cls: type[enum.IntEnum]) -> int:
    values = {int(m) for m in enum_cls}
    if isinstance(value, bool) or not isinstance(value, int) or int(value) not in values:
        names = ', '.join(f'{m.name}={int(m)}' for m in enum_cls)
        raise EncodeRangeError(field, value, f'a {enum_cls.__name__} value ({names})')
    return int(value)


def _values(field: str, values: Any, count: int, low: float, high: float, step: float,
            unit: str) -> list[float]:
    if not isinstance(values, (tuple, list)) or len(values) != count:
        raise EncodeRangeError(field, values, f'exactly {count} values')
    return [_num(f'{field}[{i}]', v, low, high, step, unit) for i, v in enumerate(values)]


def _enc_status_word(word: AmsStatusWord) -> dict[str, Any]:
    if not isinstance(word, AmsStatusWord):
        raise EncodeRangeError('status', word, 'an AmsStatusWord')
    sig = {name: _flag(attr, getattr(word, attr)) for name, attr in _STATUS_BITS}
    sig['Bank_Count'] = _int('bank_count', word.bank_count, 0, MAX_BANKS)
    sig['AMS_State'] = _member('state', word.state, AmsState)
    return sig


def _enc_status(m: AmsStatus) -> dict[str, Any]:
    sig = _enc_status_word(m.status)
    sig['Volt_min'] = _num('volt_min_v', m.volt_min_v, 0, 5.1, CELL_VOLT_STEP, 'V')
    sig['Temp_max'] = _int('temp_max_c', m.temp_max_c, 0, 255)
    sig['SOC'] = _int('soc_pct', m.soc_pct, 0, 100)
    sig['Counter'] = _int('counter', m.counter, 0, 255)
    sig['Relay_Error_AIR_Minus'] = _flag('relay_error_air_minus', m.relay_error_air_minus)
    sig['Relay_Error_AIR_Plus'] = _flag('relay_error_air_plus', m.relay_error_air_plus)
    sig['Relay_Error_Precharge'] = _flag('relay_error_precharge', m.relay_error_precharge)
    return sig


def _enc_charger_status(m: AmsChargerStatus) -> dict[str, Any]:
    sig = _enc_status_word(m.status)
    sig['SOC'] = _int('soc_pct', m.soc_pct, 0, 100)
    sig['Charger_Current'] = _num('charger_current_a', m.charger_current_a, 0, 25.5,
                                  CURRENT_STEP, 'A')
    sig['Turn_On_Charger'] = _flag('charger_on', m.charger_on)
    return sig


def _enc_car_status(m: CarStatus) -> dict[str, Any]:
    return {'CMD': _member('command', m.command, CarCommand),
            'Bank_Count': _int('bank_count', m.bank_count, 1, MAX_BANKS),
            'Counter': _int('counter', m.counter, 0, 255)}


def _enc_charger_commands(m: ChargerCommand) -> dict[str, Any]:
    return {'Start': _member('start', m.start, ChargerStart),
            'Time_Tick': _int('time_tick', m.time_tick, 0, 0xFFFF)}


def _enc_bank_group(m: Any, groups: int) -> dict[str, Any]:
    return {'Bank_ID': _int('bank', m.bank, 1, MAX_BANKS),
            'Group_ID': _int('group', m.group, 0, groups - 1)}


def _enc_cells(m: CellVoltages) -> dict[str, Any]:
    sig = _enc_bank_group(m, CELL_GROUPS)
    values = _values('voltages_v', m.voltages_v, CELLS_PER_GROUP, 0, 5.1, CELL_VOLT_STEP, 'V')
    sig.update(zip(_CELL_SIGNALS, values))
    return sig


def _enc_temps(m: CellTemperatures) -> dict[str, Any]:
    sig = _enc_bank_group(m, TEMP_GROUPS)
    values = _values('temperatures_c', m.temperatures_c, TEMPS_PER_GROUP, -128, 127, 1, 'degC')
    sig.update(zip(_TEMP_SIGNALS, values))
    return sig


def _enc_discharge(m: DischargeTemperatures) -> dict[str, Any]:
    sig = _enc_bank_group(m, TEMP_GROUPS)
    values = _values('temperatures_c', m.temperatures_c, DISCHARGE_TEMPS_PER_GROUP,
                     -128, 127, 1, 'degC')
    sig.update(zip(_DISCHARGE_SIGNALS, values))
    return sig


def _enc_error(m: AmsErrorEvent) -> dict[str, Any]:
    return {'AMS_Error_ID': _member('error', m.error, AmsError),
            'AMS_Time_Tick': _int('time_tick', m.time_tick, 0, 0xFFFF)}


def _enc_override_current(m: OverrideChargeCurrent) -> dict[str, Any]:
    return {'Charge_Current': _num('current_a', m.current_a, 0, 25.5, CURRENT_STEP, 'A')}


def _enc_override_banks(m: OverrideBankCount) -> dict[str, Any]:
    return {'Bank_Count': _int('bank_count', m.bank_count, 1, MAX_BANKS)}


_ENCODERS: dict[type, tuple[int, Callable[[Any], dict[str, Any]]]] = {
    AmsStatus: (STATUS, _enc_status), AmsChargerStatus: (CHARGER_STATUS, _enc_charger_status),
    CarStatus: (CAR_STATUS, _enc_car_status),
    ChargerCommand: (CHARGER_COMMANDS, _enc_charger_commands),
    CellVoltages: (CELL_VOLTAGES, _enc_cells), CellTemperatures: (CELL_TEMPERATURES, _enc_temps),
    DischargeTemperatures: (DISCHARGE_TEMPERATURES, _enc_discharge),
    AmsErrorEvent: (ERROR, _enc_error),
    OverrideChargeCurrent: (OVERRIDE_CHARGE_CURRENT, _enc_override_current),
    OverrideBankCount: (OVERRIDE_BANK_COUNT, _enc_override_banks),
}


class AmsCodec:
    """Frames <-> typed AMS messages at one base ID (11-bit IDs)."""

    is_extended_id = False
    _dbc_checked = False

    def __init__(self, base_id: int = DEFAULT_BASE_ID) -> None:
        highest = 0x7FF - max(OFFSETS)
        if isinstance(base_id, bool) or not isinstance(base_id, int) \
                or not 0 <= base_id <= highest:
            raise EncodeRangeError('base_id', base_id,
                                   f'0..0x{highest:X} (11-bit IDs up to base + 0x051)')
        self.base_id = base_id
        if not AmsCodec._dbc_checked:
            _check_dbc()
            AmsCodec._dbc_checked = True
        db = load_dbc('ams')
        # One dict lookup per frame: ID -> (DLC, reading builder).
        self._decode_table: dict[int, tuple[int, Callable[[bytes], Any]]] = {
            base_id + offset: (_LAYOUT[offset][0], _DECODERS[offset]) for offset in OFFSETS}
        self._encode_table: dict[type, tuple[int, Callable, Callable]] = {}
        for cls, (offset, encoder) in _ENCODERS.items():
            msg = db.get_message_by_name(_DBC_NAMES[offset])
            self._encode_table[cls] = (base_id + offset, msg.encode, encoder)
        self.arbitration_ids = frozenset(self._decode_table)

    def id_of(self, offset: int) -> int:
        """Return the CAN ID of the message at an offset (STATUS, CELL_VOLTAGES, ...)."""
        return self.base_id + offset

    def decode(self, arbitration_id: int, data: bytes) -> AmsMessage:
        """Decode one frame to its typed reading; MalformedFrameError if it cannot be one."""
        entry = self._decode_table.get(arbitration_id)
        if entry is None:
            raise MalformedFrameError(arbitration_id, data,
                                      f'not an AMS ID at base 0x{self.base_id:X}')
        length, build = entry
        # Longer is padding (AMS firmwares commonly send 8 bytes, and the seed's size rows
        # contradict its own field lists): the bytes past the layout are ignored. Shorter
        # cannot carry the fields, and beyond 8 (CAN FD) is no classic AMS frame: malformed
        # (docs/protocols.md section 1).
        if not length <= len(data) <= MAX_DLC:
            raise MalformedFrameError(arbitration_id, data,
                                      f'DLC {len(data)}, expected {length}..{MAX_DLC}')
        try:
            return build(data)
        except _Bad as exc:
            raise MalformedFrameError(arbitration_id, data, str(exc)) from None

    def encode(self, message: AmsMessage) -> Frame:
        """Encode one message; EncodeRangeError names the field and its allowed range."""
        entry = self._encode_table.get(type(message))
        if entry is None:
            raise EncodeRangeError('message', message,
                                   'one of ' + ', '.join(c.__name__ for c in _ENCODERS))
        arbitration_id, encode_signals, check = entry
        return Frame(arbitration_id, encode_signals(check(message)), False)
