"""
Formula-Student AMS (accumulator management system) protocol: docs/protocols.md section 1.

Ten 11-bit messages at ``base_id + offset`` (default base 0x300). The field layout is
``LAYOUTS`` (protocols/layout.py tables): encoders and decoders are generated from it, it is
checked against the installed ``msg_defs/ams.dbc`` when the first codec is built and
against cantools in the tests. The module
adds what a DBC cannot say (valid bank/group IDs, known enum values, DLC checks: a frame
padded beyond its layout up to 8 bytes is accepted, a shorter one is malformed; typed
readings) and checks every value before it is encoded, so a bad command fails loudly
instead of being clamped.
Readings are frozen dataclasses; enums carry the vendor's names.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Callable, Sequence, Union

from ams_can_bridge.protocols.common import EncodeRangeError, Frame, load_dbc, MalformedFrameError
from ams_can_bridge.protocols.layout import BIG, Layout, Signal

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


# --- the wire layout: one table, checked against msg_defs/ams.dbc ----------------------------
# Every AMS signal is big-endian with offset 0. The ranges are what the encoder accepts (the
# DBC cannot say that a status word counts 0..5 banks and the car status 1..5); the decoders
# are generated from the same rows, and the DBC must have the same bits at the first codec.
def _s(name: str, start: int, length: int, scale: float = 1, signed: bool = False,
       low: float | None = None, high: float | None = None, unit: str = '',
       field: str = '') -> Signal:
    return Signal(name, start, length, BIG, signed, scale, 0, low, high, unit, field,
                  flag=length == 1)


_WORD = tuple(_s(dbc, 7 - bit, 1, field=attr) for bit, (dbc, attr) in enumerate(_STATUS_BITS)
              ) + (_s('Bank_Count', 15, 3, high=MAX_BANKS, field='bank_count'),
                   _s('AMS_State', 12, 5, field='state'))


def _bank_group_signals(groups: int) -> tuple[Signal, ...]:
    return (_s('Bank_ID', 7, 3, low=1, high=MAX_BANKS, field='bank'),
            _s('Group_ID', 2, 3, high=groups - 1, field='group'))


def _series(prefix: str, count: int, field: str, **kwargs: Any) -> tuple[Signal, ...]:
    return tuple(_s(f'{prefix}_{k + 1}', 15 + 8 * k, 8, field=f'{field}[{k}]', **kwargs)
                 for k in range(count))


_VOLTS: dict[str, Any] = dict(scale=CELL_VOLT_STEP, high=5.1, unit='V')
_AMPS: dict[str, Any] = dict(scale=CURRENT_STEP, high=25.5, unit='A')
_TEMPS: dict[str, Any] = dict(signed=True, unit='degC')
LAYOUTS: dict[int, Layout] = {offset: Layout(_DBC_NAMES[offset], length, signals) for
                              offset, length, signals in (
    (STATUS, 7, _WORD + (
        _s('Volt_min', 23, 8, field='volt_min_v', **_VOLTS),
        _s('Temp_max', 31, 8, unit='degC', field='temp_max_c'),
        _s('SOC', 39, 8, high=100, unit='%', field='soc_pct'),
        _s('Counter', 47, 8, field='counter'),
        _s('Relay_Error_AIR_Minus', 48, 1, field='relay_error_air_minus'),
        _s('Relay_Error_AIR_Plus', 49, 1, field='relay_error_air_plus'),
        _s('Relay_Error_Precharge', 50, 1, field='relay_error_precharge'))),
    (CHARGER_STATUS, 5, _WORD + (
        _s('SOC', 23, 8, high=100, unit='%', field='soc_pct'),
        _s('Charger_Current', 31, 8, field='charger_current_a', **_AMPS),
        _s('Turn_On_Charger', 32, 1, field='charger_on'))),
    (CAR_STATUS, 2, (_s('CMD', 3, 4, field='command'),
                     _s('Bank_Count', 7, 4, low=1, high=MAX_BANKS, field='bank_count'),
                     _s('Counter', 15, 8, field='counter'))),
    (CHARGER_COMMANDS, 3, (_s('Start', 1, 2, field='start'),
                           _s('Time_Tick', 15, 16, field='time_tick'))),
    (CELL_VOLTAGES, 8, _bank_group_signals(CELL_GROUPS)
     + _series('Cell_Voltage', CELLS_PER_GROUP, 'voltages_v', **_VOLTS)),
    (CELL_TEMPERATURES, 6, _bank_group_signals(TEMP_GROUPS)
     + _series('Cell_Temperature', TEMPS_PER_GROUP, 'temperatures_c', **_TEMPS)),
    (DISCHARGE_TEMPERATURES, 8, _bank_group_signals(TEMP_GROUPS)
     + _series('Discharge_Temperature', DISCHARGE_TEMPS_PER_GROUP, 'temperatures_c',
               **_TEMPS)),
    (ERROR, 3, (_s('AMS_Error_ID', 7, 8, field='error'),
                _s('AMS_Time_Tick', 15, 16, field='time_tick'))),
    (OVERRIDE_CHARGE_CURRENT, 1, (_s('Charge_Current', 7, 8, field='current_a', **_AMPS),)),
    (OVERRIDE_BANK_COUNT, 1, (_s('Bank_Count', 7, 8, low=1, high=MAX_BANKS,
                                 field='bank_count'),)),
)}


def _check_dbc() -> None:
    """Fail loudly (LayoutError) if msg_defs/ams.dbc no longer has the layout of LAYOUTS."""
    db = load_dbc('ams')
    for offset, layout in LAYOUTS.items():
        layout.check_dbc(db.get_message_by_name(_DBC_NAMES[offset]), 'msg_defs/ams.dbc',
                         'AMS')


# --- decoding: the generated decoders plus what the DBC cannot say ---------------------------
# The bus thread decodes every AMS frame (about 60/s with 5 banks); the generated code reads
# the bytes as hand code would (about 1 us a frame; cantools took 4-13 us).
_D = {offset: layout.decoder() for offset, layout in LAYOUTS.items()}
_D_WORD = LAYOUTS[STATUS].decoder(*(s.name for s in _WORD))
# Status words seen so far, by the two bytes that carry them: a car sends a handful of
# distinct words, and building a frozen dataclass costs more than decoding the rest.
_WORD_CACHE: dict[int, AmsStatusWord] = {}


def _status_word(data: bytes) -> AmsStatusWord:
    key = data[0] << 8 | data[1]  # bytes or bytearray (python-can gives the latter)
    word = _WORD_CACHE.get(key)
    if word is not None:
        return word
    *flags, banks, raw_state = _D_WORD(data)
    state = _known(_STATES, raw_state, 'AMS state')
    if banks > MAX_BANKS:
        raise _Bad(f'status bank count {banks} (allowed 0..{MAX_BANKS})')
    word = AmsStatusWord(*flags, banks, state)  # type: ignore[call-arg]  # one flag per field
    _WORD_CACHE[key] = word  # bounded: at most 2**16 words
    return word


def _known(members: dict[int, Any], raw: int, what: str) -> Any:
    """Return the enum member of a raw value; _Bad for a value the vendor does not name."""
    member = members.get(raw)
    if member is None:
        raise _Bad(f'unknown {what} {raw} (known {min(members)}..{max(members)})')
    return member


def _bank_group(bank: int, group: int, groups: int) -> None:
    if not 1 <= bank <= MAX_BANKS:
        raise _Bad(f'bank ID {bank} (allowed 1..{MAX_BANKS})')
    if group >= groups:
        raise _Bad(f'group ID {group} (allowed 0..{groups - 1})')


def _dec_car_status(data: bytes) -> CarStatus:
    raw, banks, counter = _D[CAR_STATUS](data)
    command = _known(_COMMANDS, raw, 'car command')
    if not 1 <= banks <= MAX_BANKS:
        raise _Bad(f'car status bank count {banks} (allowed 1..{MAX_BANKS})')
    return CarStatus(command, banks, counter)


def _dec_charger_commands(data: bytes) -> ChargerCommand:
    raw, tick = _D[CHARGER_COMMANDS](data)
    return ChargerCommand(_known(_STARTS, raw, 'charger start command'), tick)


def _series_decoder(offset: int, groups: int, cls: type) -> Callable[[bytes], Any]:
    decode = _D[offset]

    def build(data: bytes) -> Any:
        bank, group, *values = decode(data)
        _bank_group(bank, group, groups)
        return cls(bank, group, tuple(values))
    return build


def _dec_error(data: bytes) -> AmsErrorEvent:
    raw, tick = _D[ERROR](data)
    return AmsErrorEvent(_known(_ERRORS, raw, 'AMS error ID'), tick)


def _dec_override_banks(data: bytes) -> OverrideBankCount:
    banks, = _D[OVERRIDE_BANK_COUNT](data)
    if not 1 <= banks <= MAX_BANKS:
        raise _Bad(f'override bank count {banks} (allowed 1..{MAX_BANKS})')
    return OverrideBankCount(banks)


_DECODERS: dict[int, Callable[[bytes], Any]] = {
    STATUS: LAYOUTS[STATUS].decoder(
        'Volt_min', 'Temp_max', 'SOC', 'Counter', 'Relay_Error_AIR_Minus',
        'Relay_Error_AIR_Plus', 'Relay_Error_Precharge', into=AmsStatus, head=_status_word),
    CHARGER_STATUS: LAYOUTS[CHARGER_STATUS].decoder(
        'SOC', 'Charger_Current', 'Turn_On_Charger', into=AmsChargerStatus, head=_status_word),
    CAR_STATUS: _dec_car_status,
    CHARGER_COMMANDS: _dec_charger_commands,
    CELL_VOLTAGES: _series_decoder(CELL_VOLTAGES, CELL_GROUPS, CellVoltages),
    CELL_TEMPERATURES: _series_decoder(CELL_TEMPERATURES, TEMP_GROUPS, CellTemperatures),
    DISCHARGE_TEMPERATURES: _series_decoder(DISCHARGE_TEMPERATURES, TEMP_GROUPS,
                                            DischargeTemperatures),
    ERROR: _dec_error,
    OVERRIDE_CHARGE_CURRENT: LAYOUTS[OVERRIDE_CHARGE_CURRENT].decoder(
        into=OverrideChargeCurrent),
    OVERRIDE_BANK_COUNT: _dec_override_banks,
}


# --- encoding: what the DBC cannot say, then the generated encoder checks every value --------
def _member(field: str, value: Any, enum_cls: type[enum.IntEnum]) -> int:
    values = {int(m) for m in enum_cls}
    if isinstance(value, bool) or not isinstance(value, int) or int(value) not in values:
        names = ', '.join(f'{m.name}={int(m)}' for m in enum_cls)
        raise EncodeRangeError(field, value, f'a {enum_cls.__name__} value ({names})')
    return int(value)


def _values(field: str, values: Any, count: int) -> tuple:
    if not isinstance(values, (tuple, list)) or len(values) != count:
        raise EncodeRangeError(field, values, f'exactly {count} values')
    return tuple(values)


def _word(word: AmsStatusWord) -> list[Any]:
    if not isinstance(word, AmsStatusWord):
        raise EncodeRangeError('status', word, 'an AmsStatusWord')
    return [getattr(word, attr) for _, attr in _STATUS_BITS] + [
        word.bank_count, _member('state', word.state, AmsState)]


# reading type -> (offset, its values in the layout's signal order)
_ENCODERS: dict[type, tuple[int, Callable[[Any], Sequence[Any]]]] = {
    AmsStatus: (STATUS, lambda m: _word(m.status) + [
        m.volt_min_v, m.temp_max_c, m.soc_pct, m.counter, m.relay_error_air_minus,
        m.relay_error_air_plus, m.relay_error_precharge]),
    AmsChargerStatus: (CHARGER_STATUS, lambda m: _word(m.status) + [
        m.soc_pct, m.charger_current_a, m.charger_on]),
    CarStatus: (CAR_STATUS, lambda m: (
        _member('command', m.command, CarCommand), m.bank_count, m.counter)),
    ChargerCommand: (CHARGER_COMMANDS, lambda m: (
        _member('start', m.start, ChargerStart), m.time_tick)),
    CellVoltages: (CELL_VOLTAGES, lambda m: (m.bank, m.group) + _values(
        'voltages_v', m.voltages_v, CELLS_PER_GROUP)),
    CellTemperatures: (CELL_TEMPERATURES, lambda m: (m.bank, m.group) + _values(
        'temperatures_c', m.temperatures_c, TEMPS_PER_GROUP)),
    DischargeTemperatures: (DISCHARGE_TEMPERATURES, lambda m: (m.bank, m.group) + _values(
        'temperatures_c', m.temperatures_c, DISCHARGE_TEMPS_PER_GROUP)),
    AmsErrorEvent: (ERROR, lambda m: (_member('error', m.error, AmsError), m.time_tick)),
    OverrideChargeCurrent: (OVERRIDE_CHARGE_CURRENT, lambda m: (m.current_a,)),
    OverrideBankCount: (OVERRIDE_BANK_COUNT, lambda m: (m.bank_count,)),
}
_ENCODE = {offset: layout.encoder() for offset, layout in LAYOUTS.items()}


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
        # One dict lookup per frame: ID -> (DLC, reading builder).
        self._decode_table: dict[int, tuple[int, Callable[[bytes], Any]]] = {
            base_id + offset: (LAYOUTS[offset].length, _DECODERS[offset])
            for offset in OFFSETS}
        self._encode_table: dict[type, tuple[int, Callable, Callable]] = {
            cls: (base_id + offset, _ENCODE[offset], values)
            for cls, (offset, values) in _ENCODERS.items()}
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
        arbitration_id, encode, values = entry
        return Frame(arbitration_id, encode(*values(message)), False)
