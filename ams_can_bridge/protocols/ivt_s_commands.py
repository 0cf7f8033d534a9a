# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
IVT-S commands (0x411, host -> sensor) and answers (0x511), as doc/protocols.md 2.2-2.3 says.

Answers to the commands the bridge does not send decode as ``OtherAnswer``. msg_defs/ivt_s.dbc
has no layout for these two IDs: the tables below (the vendor DBC's start bits) are checked
against hand-typed golden frames.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import enum
from typing import Any, Callable

from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.common import check_dlc, Frame
from ams_can_bridge.protocols.ivt_s import COMMAND_ID, IvtMux, RESPONSE_ID
from ams_can_bridge.protocols.layout import BadValue, Layout, Signal

DLC = 8

# Command mux IDs (DBC VtID_Cmd / IVT_Msg_Cmd signal names).
SET_CONFIG_RESULT = 0x20  # + result: _2n_Conf_TriggerMode/Endianess/Sign/CycleTime
RESET_ERR_LOG = 0x30  # _30_Reset_Item (16 bit), _30_Reset_Device_SN (32 bit)
STORE = 0x32
SET_MODE = 0x34  # _34_Actual_Mode (byte 1 bit 0), _34_Startup_Mode (byte 2 bit 0)
RESTART_DEFAULT = 0x3D
RESTART = 0x3F
GET_MEAS_ERROR = 0x40
GET_SYSTEM_ERROR = 0x41
GET_CONFIG_RESULT = 0x60  # + result
GET_MODE = 0x74
GET_SERIAL_NR = 0x7B

# Answer mux IDs (DBC IVT_ID_Response value table).
RESP_MEAS_ERROR = 0x80
RESP_SYSTEM_ERROR = 0x81
RESP_CONFIG_RESULT = 0xA0  # + result
RESP_RESET_ERR_LOG = 0xB0
RESP_STORE = 0xB2
RESP_MODE = 0xB4
RESP_SERIAL_NR = 0xBB
RESP_ALIVE = 0xBF  # Resp_Get_Set_ALIVE: sent after a restart
RESP_WRONG_COMMAND = 0xFF

# _30_Reset_Item values (DBC value table of _B0_Resp_Reset_Item).
RESET_ALL_MEASUREMENT_ERRORS = 0x0000
RESET_ALL_SYSTEM_ERRORS = 0x0100

CYCLE_MAX_MS = 0xFFFF
# ivts' example writes a disabled result with a non-zero time ("must have some non-zero
# value to avoid message error"): a result switched off keeps this cycle time.
DISABLED_CYCLE_MS = 60


class TriggerMode(enum.IntEnum):
    """How a result is sent (DBC VtTriggerMode)."""

    DISABLED = 0
    TRIGGERED = 1
    CYCLIC = 2


ERROR_ITEMS = {  # DBC _80_Resp_MeasError_Item / _81_Resp_SystemError_Item value tables
    RESP_MEAS_ERROR: {
        0: 'all measurement errors', 1: 'ADC interrupt', 2: 'overflow ADC ch 1',
        3: 'underflow ADC ch 1', 4: 'overflow ADC ch 2', 5: 'underflow ADC ch 2',
        6: 'Vref', 7: 'current measurement implausible', 8: 'thermal EMF correction',
        9: 'I1 open circuit', 10: 'U1 open circuit', 11: 'U2 open circuit',
        12: 'U3 open circuit', 13: 'ntc-h open circuit', 14: 'ntc-l open circuit',
        15: 'calibration data'},
    RESP_SYSTEM_ERROR: {
        0: 'all system errors', 1: 'code CRC', 2: 'parameter CRC', 3: 'CAN receive data',
        4: 'CAN transmit data', 5: 'overtemperature', 6: 'undertemperature',
        7: 'power failure', 8: 'system clock', 9: 'system init', 10: 'configuration',
        11: 'overcurrent detection', 12: 'EEPROM read/write', 13: 'ADC clock',
        14: 'reset illegal opcode', 15: 'reset watchdog', 16: 'reset EMC'},
}


@dataclass(frozen=True)
class ResultConfig:
    """
    One result's configuration (command 0x2n, answer 0xAn).

    error_masks is byte 1 bit 5, a global setting of the sensor (the last one written holds
    for every result): the measurement and system error masks set the result state bits 6
    and 7 (off, the factory setting: only CRC and Vref errors set them).
    """

    kind: IvtMux
    mode: TriggerMode
    cycle_ms: int
    little_endian: bool = False
    sign_inverted: bool = False
    error_masks: bool = False

    @property
    def byte_order(self) -> str:
        """Return 'little' or 'big', as the bridge parameter byte_order names it."""
        return 'little' if self.little_endian else 'big'

    def text(self) -> str:
        """Describe as 'cyclic 100 ms, big-endian, sign normal'."""
        mode = (f'cyclic {self.cycle_ms} ms' if self.mode is TriggerMode.CYCLIC
                else self.mode.name.lower())
        return (f'{mode}, {self.byte_order}-endian, sign '
                + ('inverted' if self.sign_inverted else 'normal')
                + (', error masks in the result state' if self.error_masks else ''))


@dataclass(frozen=True)
class ModeAnswer:
    """0xB4: the sensor's mode now and after power-up."""

    running: bool
    startup_running: bool


@dataclass(frozen=True)
class StoreAnswer:
    """0xB2: the configuration was stored (or the store was answered)."""


@dataclass(frozen=True)
class AliveAnswer:
    """0xBF: the sensor (re)started; command ID and serial number."""

    command_id: int
    serial: int


@dataclass(frozen=True)
class SerialAnswer:
    """0xBB: the serial number."""

    serial: int


@dataclass(frozen=True)
class ResetAnswer:
    """0xB0: a reset of error/log data was answered."""

    item: int
    serial: int


@dataclass(frozen=True)
class ErrorAnswer:
    """0x80 (measurement) / 0x81 (system): an error item and its count or bit mask."""

    system: bool
    item: int
    count_mask: int

    def text(self) -> str:
        """Describe as 'system error item 5 (overtemperature): 0x0003'."""
        table = ERROR_ITEMS[RESP_SYSTEM_ERROR if self.system else RESP_MEAS_ERROR]
        name = table.get(self.item, 'unknown item')
        return (f'{"system" if self.system else "measurement"} error item {self.item} '
                f'({name}): 0x{self.count_mask:04X}')


@dataclass(frozen=True)
class WrongCommand:
    """0xFF: the sensor did not accept a command (byte 1 = its mux ID)."""

    command: int


@dataclass(frozen=True)
class OtherAnswer:
    """Any other answer mux ID: counted, never interpreted."""

    mux: int
    data: bytes


IvtAnswer = (ResultConfig | ModeAnswer | StoreAnswer | AliveAnswer | SerialAnswer
             | ResetAnswer | ErrorAnswer | WrongCommand | OtherAnswer)


# --- the layouts (vendor DBC IVT-S_12082020.dbc: start|length, Motorola) ------------------
def _layout(name: str, *signals: Signal) -> Layout:
    """One 0x411 / 0x511 message: the mux byte 0 (IVT_ID_Cmd / IVT_ID_Response 7|8) first."""
    return Layout(name, DLC, (Signal('IVT_ID', 7, 8, field='IVT-S mux ID'),) + signals)


# 0x2n / 0xAn (_2n_Conf_*, _An_Resp_*), in the order of ResultConfig. Byte 1 bit 5 is not in
# the DBC: the datasheet's set config result (section 2.3); bit 4 is reserved and stays 0.
CONFIG = _layout(
    'Conf_Result',
    Signal('Conf_TriggerMode', 9, 2, lookup=tuple(TriggerMode), field='IVT-S trigger mode',
           check='trigger mode {value} (allowed {low}..{high})'),  # 3 is not defined
    Signal('Conf_CycleTime', 23, 16, unit='ms', field='IVT-S cycle time'),
    Signal('Conf_Endianess', 14, 1, flag=True, field='little_endian'),
    Signal('Conf_Sign', 15, 1, flag=True, field='sign_inverted'),
    Signal('Conf_Error_Masks', 13, 1, flag=True, field='error_masks'))
EMPTY = _layout('Dummy')  # get, store, restart: the DBC's *_dummy byte is 0
MODE = _layout('Mode', Signal('Actual_Mode', 8, 1, flag=True, field='running'),
               Signal('Startup_Mode', 16, 1, flag=True, field='startup_running'))
RESET = _layout('Reset', Signal('Reset_Item', 15, 16, field='IVT-S reset item'),
                Signal('Reset_Device_SN', 31, 32, field='IVT-S serial number'))
ALIVE = _layout('Restart_Alive', Signal('Restart_Alive_Cmd_ID', 15, 16, field='command_id'),
                Signal('Restart_Alive_SN', 31, 32, field='IVT-S serial number'))
SERIAL = _layout('Serien_Nr', Signal('Resp_Serien_Nr', 15, 32, field='IVT-S serial number'))
ERROR = _layout('Error', Signal('Error_Item', 15, 8, field='item'),
                Signal('Error_Count_Mask', 23, 16, field='count_mask'))
WRONG = _layout('Wrong_Command', Signal('Wrong_Command', 15, 8, field='command'))

# Answer mux ID -> (reading, layout, the reading's first fields that the mux ID itself says:
# the result of 0xAn, system or measurement of 0x81 / 0x80); the other fields follow the
# mux byte in the layout's order.
_ANSWERS: dict[int, tuple[type, Layout, tuple]] = {
    **{RESP_CONFIG_RESULT + kind: (ResultConfig, CONFIG, (kind,)) for kind in IvtMux},
    RESP_MEAS_ERROR: (ErrorAnswer, ERROR, (False,)),
    RESP_SYSTEM_ERROR: (ErrorAnswer, ERROR, (True,)),
    RESP_MODE: (ModeAnswer, MODE, ()),
    RESP_STORE: (StoreAnswer, EMPTY, ()),
    RESP_ALIVE: (AliveAnswer, ALIVE, ()),
    RESP_SERIAL_NR: (SerialAnswer, SERIAL, ()),
    RESP_RESET_ERR_LOG: (ResetAnswer, RESET, ()),
    RESP_WRONG_COMMAND: (WrongCommand, WRONG, ()),
}


def _reading(reading: type, known: tuple) -> Callable[..., Any]:
    return lambda _mux, *values: reading(*known, *values)


_DECODE = {mux: layout.decoder(into=_reading(reading, known))
           for mux, (reading, layout, known) in _ANSWERS.items()}
_ENCODE = {mux: layout.encoder() for mux, (_, layout, _) in _ANSWERS.items()}
_MUX = {(reading, known): mux for mux, (reading, _, known) in _ANSWERS.items()}
_KNOWN = {reading: len(known) for reading, _, known in _ANSWERS.values()}
_E_CONFIG = {kind: CONFIG.replace('Conf_CycleTime', field=f'IVT-S {kind.name} cycle time')
             .encoder() for kind in IvtMux}  # the error names the result
_E_EMPTY, _E_MODE, _E_RESET = EMPTY.encoder(), MODE.encoder(), RESET.encoder()


def _command(data: bytes) -> Frame:
    return Frame(COMMAND_ID, data, False)


# --- commands ---------------------------------------------------------------------------
def set_config(config: ResultConfig) -> Frame:
    """0x2n: a result's trigger mode, byte order, sign and cycle time (stop mode only)."""
    kind, *values = dataclasses.astuple(config)  # the layout's order
    return _command(_E_CONFIG[kind](SET_CONFIG_RESULT + kind, *values))


def _empty(mux: int, doc: str) -> Callable[[], Frame]:
    """Return a command that is its mux ID alone (the DBC's *_dummy byte and the rest 0)."""
    def command() -> Frame:
        return _command(_E_EMPTY(mux))
    command.__doc__ = doc
    return command


get_mode = _empty(GET_MODE, '0x74: ask for the mode (answer 0xB4).')
store = _empty(STORE, "0x32: store the configuration in the sensor's non-volatile memory "
               '(answer 0xB2).')
restart = _empty(RESTART, '0x3F: restart the sensor (it sends 0xBF when alive again).')
get_serial = _empty(GET_SERIAL_NR, '0x7B: ask for the serial number (answer 0xBB).')


def get_config(kind: IvtMux) -> Frame:
    """0x6n: ask for a result's configuration (answer 0xAn)."""
    return _command(_E_EMPTY(GET_CONFIG_RESULT + IvtMux(kind)))


def set_mode(running: bool, startup_running: bool = True) -> Frame:
    """0x34: run or stop now; bytes 2 = the mode after power-up (kept RUN by default)."""
    return _command(_E_MODE(SET_MODE, running, startup_running))


def reset_errors(item: int, serial: int) -> Frame:
    """0x30: reset an error/log item (16 bit) of the sensor with this serial number."""
    return _command(_E_RESET(RESET_ERR_LOG, item, serial))


# --- answers ----------------------------------------------------------------------------
def _decoded(decode: Callable[[bytes], Any], arbitration_id: int, data: bytes) -> Any:
    try:
        return decode(data)
    except BadValue as exc:  # a trigger mode that is not defined
        raise MalformedFrameError(arbitration_id, data, str(exc)) from None


def decode_answer(data: bytes) -> IvtAnswer:
    """Decode one 0x511 frame; MalformedFrameError for a wrong DLC or impossible value."""
    check_dlc(RESPONSE_ID, data, DLC)
    decode = _DECODE.get(data[0])
    if decode is None:
        return OtherAnswer(data[0], bytes(data))
    answer: IvtAnswer = _decoded(decode, RESPONSE_ID, data)  # the reading of its layout
    return answer


def decode_config(arbitration_id: int, data: bytes) -> ResultConfig:
    """Decode the configuration layout of 0x2n (command) / 0xAn (answer)."""
    config: ResultConfig = _decoded(_DECODE[RESP_CONFIG_RESULT + (data[0] & 0x07)],
                                    arbitration_id, data)
    return config


def decode_command(data: bytes) -> tuple[int, bytes]:
    """Split a 0x411 frame into (mux, data) for the simulator; MalformedFrameError if not 8."""
    check_dlc(COMMAND_ID, data, DLC)
    return data[0], bytes(data)


def encode_answer(answer: IvtAnswer) -> Frame:
    """Build a 0x511 frame (the simulator's side)."""
    if isinstance(answer, OtherAnswer):
        data = answer.data + bytes(DLC - len(answer.data))
    else:
        values = dataclasses.astuple(answer)
        known = _KNOWN[type(answer)]  # the first fields, carried in the mux ID
        mux = _MUX[type(answer), tuple(values[:known])]
        data = _ENCODE[mux](mux, *values[known:])
    return Frame(RESPONSE_ID, data, False)
