# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Formula-Student AMS protocol: frames <-> typed readings (doc/protocols.md section 1).

The bits are the ``LAYOUTS`` table below (checked against msg_defs/ams.dbc); every value is
checked before it is encoded, so a bad command fails loudly instead of being clamped.
"""
from __future__ import annotations

import enum
import functools
from dataclasses import dataclass, fields
from typing import Any, Callable, Union

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import Frame, load_dbc, TEMP_C_MAX
from ams_can_bridge.protocols.layout import BadValue, Layout, Signal

DEFAULT_BASE_ID = 0x300

# Offsets from the base ID (doc/protocols.md section 1 table).
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

# The status word's bits 7..0 as msg_defs/ams.dbc names them (AmsStatusWord's order).
_STATUS_BITS = ('AIR_Plus', 'AIR_Minus', 'Precharge_Relay', 'Warn_Volt', 'Warn_Temp',
                'HVDC_Interlock', 'IMD_Error', 'AMS_Error')
# The two status frames' readings start with the status word; the series frames' end with
# one tuple of values after bank and group.
_WORD_FRAMES = (STATUS, CHARGER_STATUS)
_SERIES = (CELL_VOLTAGES, CELL_TEMPERATURES, DISCHARGE_TEMPERATURES)


# --- the wire layout: one table, checked against msg_defs/ams.dbc ----------------------------
# Every AMS signal is big-endian with offset 0. The ranges are what the encoder accepts and,
# where a row has a check, what a decoded frame may carry (the DBC cannot say that a status
# word counts 0..5 banks and the car status 1..5, nor which enum values exist).
_ALLOWED = ' {value} (allowed {low:g}..{high:g})'
_UNKNOWN = ' {value} (known {low}..{high})'
_WORD = tuple(Signal(dbc, 7 - bit, 1, field=attr.name, flag=True)
              for bit, (dbc, attr) in enumerate(zip(_STATUS_BITS, fields(AmsStatusWord)))) + (
    Signal('Bank_Count', 15, 3, high=MAX_BANKS, field='bank_count',
           check='status bank count' + _ALLOWED),
    Signal('AMS_State', 12, 5, field='state', lookup=tuple(AmsState),
           check='unknown AMS state' + _UNKNOWN))


def _series(groups: int, prefix: str, count: int, field: str,
            **kwargs: Any) -> tuple[Signal, ...]:
    """Bank ID and group ID, then count values of a byte each."""
    return (Signal('Bank_ID', 7, 3, low=1, high=MAX_BANKS, field='bank',
                   check='bank ID' + _ALLOWED),
            Signal('Group_ID', 2, 3, high=groups - 1, field='group',
                   check='group ID' + _ALLOWED)) + tuple(
        Signal(f'{prefix}_{k + 1}', 15 + 8 * k, 8, field=f'{field}[{k}]', **kwargs)
        for k in range(count))


_VOLTS: dict[str, Any] = dict(scale=CELL_VOLT_STEP, high=5.1, unit='V')
_AMPS: dict[str, Any] = dict(scale=CURRENT_STEP, high=25.5, unit='A')
_TEMPS: dict[str, Any] = dict(signed=True, unit='degC')
_BANKS: dict[str, Any] = dict(low=1, high=MAX_BANKS, field='bank_count')
# offset -> its reading, the message as msg_defs/ams.dbc names it, its length and signals
_MESSAGES: tuple[tuple[int, type, str, int, tuple[Signal, ...]], ...] = (
    (STATUS, AmsStatus, 'AMS_Status', 7, _WORD + (
        Signal('Volt_min', 23, 8, field='volt_min_v', **_VOLTS),
        Signal('Temp_max', 31, 8, high=TEMP_C_MAX, unit='degC', field='temp_max_c',
               check='Temp_max {value} degC (allowed {low:g}..{high:g}: above is no '
               'battery temperature)'),
        Signal('SOC', 39, 8, high=100, unit='%', field='soc_pct'),
        Signal('Counter', 47, 8, field='counter'),
        Signal('Relay_Error_AIR_Minus', 48, 1, field='relay_error_air_minus', flag=True),
        Signal('Relay_Error_AIR_Plus', 49, 1, field='relay_error_air_plus', flag=True),
        Signal('Relay_Error_Precharge', 50, 1, field='relay_error_precharge', flag=True))),
    (CHARGER_STATUS, AmsChargerStatus, 'AMS_Status_Charger', 5, _WORD + (
        Signal('SOC', 23, 8, high=100, unit='%', field='soc_pct'),
        Signal('Charger_Current', 31, 8, field='charger_current_a', **_AMPS),
        Signal('Turn_On_Charger', 32, 1, field='charger_on', flag=True))),
    (CAR_STATUS, CarStatus, 'CAR_Status', 2, (
        Signal('CMD', 3, 4, field='command', lookup=tuple(CarCommand),
               check='unknown car command' + _UNKNOWN),
        Signal('Bank_Count', 7, 4, **_BANKS, check='car status bank count' + _ALLOWED),
        Signal('Counter', 15, 8, field='counter'))),
    (CHARGER_COMMANDS, ChargerCommand, 'CHARGER_Commands', 3, (
        Signal('Start', 1, 2, field='start', lookup=tuple(ChargerStart),
               check='unknown charger start command' + _UNKNOWN),
        Signal('Time_Tick', 15, 16, field='time_tick'))),
    (CELL_VOLTAGES, CellVoltages, 'AMS_Cell_Voltages', 8, _series(
        CELL_GROUPS, 'Cell_Voltage', CELLS_PER_GROUP, 'voltages_v', **_VOLTS)),
    (CELL_TEMPERATURES, CellTemperatures, 'AMS_Cell_Temperatures', 6, _series(
        TEMP_GROUPS, 'Cell_Temperature', TEMPS_PER_GROUP, 'temperatures_c', **_TEMPS)),
    (DISCHARGE_TEMPERATURES, DischargeTemperatures, 'AMS_Discharge_Temperatures', 8, _series(
        TEMP_GROUPS, 'Discharge_Temperature', DISCHARGE_TEMPS_PER_GROUP, 'temperatures_c',
        **_TEMPS)),
    (ERROR, AmsErrorEvent, 'AMS_Error', 3, (  # error IDs count from 1
        Signal('AMS_Error_ID', 7, 8, field='error', lookup=(None, *AmsError),
               check='unknown AMS error ID' + _UNKNOWN),
        Signal('AMS_Time_Tick', 15, 16, field='time_tick'))),
    (OVERRIDE_CHARGE_CURRENT, OverrideChargeCurrent, 'CHARGER_Override_Charge_Current', 1, (
        Signal('Charge_Current', 7, 8, field='current_a', **_AMPS),)),
    (OVERRIDE_BANK_COUNT, OverrideBankCount, 'CHARGER_Override_Bank_Count', 1, (
        Signal('Bank_Count', 7, 8, **_BANKS, check='override bank count' + _ALLOWED),)),
)
LAYOUTS = {offset: Layout(name, length, signals) for offset, _, name, length, signals in _MESSAGES}


@functools.cache
def check_dbc() -> None:
    """Fail loudly (LayoutError) if msg_defs/ams.dbc no longer has the layout of LAYOUTS."""
    db = load_dbc('ams')
    for layout in LAYOUTS.values():
        layout.check_dbc(db.get_message_by_name(layout.name), 'msg_defs/ams.dbc', 'AMS')


# --- decoding: generated from the table, checks included -------------------------------------
# The bus thread decodes every AMS frame (about 60/s with 5 banks); the generated code reads
# the bytes as hand code would (several times faster than cantools: bench/README.md).
_D_WORD = LAYOUTS[STATUS].decoder(*(s.name for s in _WORD), into=AmsStatusWord)
# Status words seen so far, by the two bytes that carry them: a car sends a handful of
# distinct words, and building a frozen dataclass costs more than decoding the rest.
_WORD_CACHE: dict[int, AmsStatusWord] = {}


def _status_word(data: bytes) -> AmsStatusWord:
    key = data[0] << 8 | data[1]  # bytes or bytearray (python-can gives the latter)
    word = _WORD_CACHE.get(key)
    if word is None:  # BadValue for a word the AMS cannot send: never cached
        word = _WORD_CACHE[key] = _D_WORD(data)  # bounded: at most 2**16 words
    return word


def _decoder(offset: int, reading: type) -> Callable[[bytes], Any]:
    layout = LAYOUTS[offset]
    if offset in _WORD_FRAMES:
        return layout.decoder(*(s.name for s in layout.signals[len(_WORD):]), into=reading,
                              head=_status_word)
    return layout.decoder(into=reading, tail=len(layout.signals) - 2 if offset in _SERIES else 0)


_DECODERS = {offset: _decoder(offset, reading) for offset, reading, *_ in _MESSAGES}


# --- encoding: the generated encoder checks every value (enum members, ranges, steps) --------
def _values(offset: int, message: Any) -> list[Any]:
    """Return a reading's values in its layout's order (status word and series spread out)."""
    values = [getattr(message, f.name) for f in fields(message)]
    if offset in _WORD_FRAMES:
        word = values.pop(0)
        if not isinstance(word, AmsStatusWord):
            raise EncodeRangeError('status', word, 'an AmsStatusWord')
        values[:0] = [getattr(word, f.name) for f in fields(word)]
    elif offset in _SERIES:
        series, count = values.pop(), len(LAYOUTS[offset].signals) - 2
        if not isinstance(series, (tuple, list)) or len(series) != count:
            raise EncodeRangeError(fields(message)[-1].name, series, f'exactly {count} values')
        values += series
    return values


_ENCODE = {offset: layout.encoder() for offset, layout in LAYOUTS.items()}
_OFFSET_OF = {reading: offset for offset, reading, *_ in _MESSAGES}


class AmsCodec:
    """Frames <-> typed AMS messages at one base ID (11-bit IDs)."""

    is_extended_id = False

    def __init__(self, base_id: int = DEFAULT_BASE_ID) -> None:
        highest = 0x7FF - max(LAYOUTS)
        if isinstance(base_id, bool) or not isinstance(base_id, int) \
                or not 0 <= base_id <= highest:
            raise EncodeRangeError('base_id', base_id,
                                   f'0..0x{highest:X} (11-bit IDs up to base + 0x051)')
        self.base_id = base_id
        # One dict lookup per frame: ID -> (DLC, reading builder).
        self._decode_table: dict[int, tuple[int, Callable[[bytes], AmsMessage]]] = {
            base_id + offset: (layout.length, _DECODERS[offset])
            for offset, layout in LAYOUTS.items()}
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
        # Padding up to 8 bytes is ignored; shorter, or CAN FD, is malformed (section 1.7).
        if not length <= len(data) <= MAX_DLC:
            raise MalformedFrameError(arbitration_id, data,
                                      f'DLC {len(data)}, expected {length}..{MAX_DLC}')
        try:
            return build(data)
        except BadValue as exc:
            raise MalformedFrameError(arbitration_id, data, str(exc)) from None

    def encode(self, message: AmsMessage) -> Frame:
        """Encode one message; EncodeRangeError names the field and its allowed range."""
        offset = _OFFSET_OF.get(type(message))
        if offset is None:
            raise EncodeRangeError('message', message,
                                   'one of ' + ', '.join(c.__name__ for c in _OFFSET_OF))
        return Frame(self.base_id + offset, _ENCODE[offset](*_values(offset, message)), False)
