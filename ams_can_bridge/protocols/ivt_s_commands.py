"""
IVT-S commands (0x411, host -> sensor) and answers (0x511, sensor -> host).

The layout is in docs/protocols.md section 2. Both are DLC 8 with a mux byte 0 (the
vendor DBC IVT-S_12082020.dbc: IVT_ID_Cmd / IVT_ID_Response); unused bytes are 0.
Multi-byte fields are big-endian whatever the result byte order is set to (the DBC's
Motorola signals). Only what the public sources confirm is encoded here; the other
commands of the DBC (CAN IDs, thresholds, triggers, log data) are not used by the bridge,
and answers to them decode as ``OtherAnswer``.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass

from ams_can_bridge.protocols.common import EncodeRangeError, Frame, MalformedFrameError
from ams_can_bridge.protocols.ivt_s import COMMAND_ID, IvtMux, RESPONSE_ID

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

# Configuration byte 1 (DBC: TriggerMode 9|2 = bits 1..0, Endianess 14|1 = bit 6,
# Sign 15|1 = bit 7). Bits 5..4 are not in the DBC: written 0, as ivts (flags=0) and
# Stm32-vcu (0x42) do.
MODE_MASK = 0x03
ENDIANESS_BIT = 0x40  # 1 = little-endian (Stm32-vcu writes 0x42 and decodes LE)
SIGN_BIT = 0x80
CYCLE_MAX_MS = 0xFFFF


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
    """One result's configuration (command 0x2n, answer 0xAn)."""

    kind: IvtMux
    mode: TriggerMode
    cycle_ms: int
    little_endian: bool = False
    sign_inverted: bool = False

    @property
    def byte_order(self) -> str:
        """Return 'little' or 'big', as the bridge parameter byte_order names it."""
        return 'little' if self.little_endian else 'big'

    def text(self) -> str:
        """Describe as 'cyclic 100 ms, big-endian, sign normal'."""
        mode = (f'cyclic {self.cycle_ms} ms' if self.mode is TriggerMode.CYCLIC
                else self.mode.name.lower())
        return (f'{mode}, {self.byte_order}-endian, sign '
                + ('inverted' if self.sign_inverted else 'normal'))


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


def _frame(*data: int) -> Frame:
    return Frame(COMMAND_ID, bytes(data) + bytes(DLC - len(data)), False)


def _u32(value: int, what: str) -> bytes:
    if not 0 <= value <= 0xFFFFFFFF:
        raise EncodeRangeError(what, value, '0..0xFFFFFFFF')
    return value.to_bytes(4, 'big')


# --- commands ---------------------------------------------------------------------------
def set_config(config: ResultConfig) -> Frame:
    """0x2n: a result's trigger mode, byte order, sign and cycle time (stop mode only)."""
    if not 0 <= config.cycle_ms <= CYCLE_MAX_MS:
        raise EncodeRangeError(f'IVT-S {IvtMux(config.kind).name} cycle time',
                               config.cycle_ms, f'0..{CYCLE_MAX_MS} ms')
    flags = (int(TriggerMode(config.mode)) | (ENDIANESS_BIT if config.little_endian else 0)
             | (SIGN_BIT if config.sign_inverted else 0))
    return _frame(SET_CONFIG_RESULT + int(config.kind), flags, config.cycle_ms >> 8,
                  config.cycle_ms & 0xFF)


def get_config(kind: IvtMux) -> Frame:
    """0x6n: ask for a result's configuration (answer 0xAn)."""
    return _frame(GET_CONFIG_RESULT + int(kind))


def set_mode(running: bool, startup_running: bool = True) -> Frame:
    """0x34: run or stop now; bytes 2 = the mode after power-up (kept RUN by default)."""
    return _frame(SET_MODE, int(bool(running)), int(bool(startup_running)))


def get_mode() -> Frame:
    """0x74: ask for the mode (answer 0xB4)."""
    return _frame(GET_MODE)


def store() -> Frame:
    """0x32: store the configuration in the sensor's non-volatile memory (answer 0xB2)."""
    return _frame(STORE)


def restart() -> Frame:
    """0x3F: restart the sensor (it sends 0xBF when alive again)."""
    return _frame(RESTART)


def get_serial() -> Frame:
    """0x7B: ask for the serial number (answer 0xBB)."""
    return _frame(GET_SERIAL_NR)


def reset_errors(item: int, serial: int) -> Frame:
    """0x30: reset an error/log item (16 bit) of the sensor with this serial number."""
    if not 0 <= item <= 0xFFFF:
        raise EncodeRangeError('IVT-S reset item', item, '0..0xFFFF')
    return Frame(COMMAND_ID, bytes([RESET_ERR_LOG]) + item.to_bytes(2, 'big')
                 + _u32(serial, 'IVT-S serial number') + b'\x00', False)


# --- answers ----------------------------------------------------------------------------
def decode_answer(data: bytes) -> IvtAnswer:
    """Decode one 0x511 frame; MalformedFrameError for a wrong DLC or impossible value."""
    if len(data) != DLC:
        raise MalformedFrameError(RESPONSE_ID, data, f'DLC {len(data)}, expected {DLC}')
    mux = data[0]
    if RESP_CONFIG_RESULT <= mux <= RESP_CONFIG_RESULT + 7:
        return decode_config(RESPONSE_ID, data)
    if mux == RESP_MODE:
        return ModeAnswer(bool(data[1] & 1), bool(data[2] & 1))
    if mux == RESP_STORE:
        return StoreAnswer()
    if mux == RESP_ALIVE:
        return AliveAnswer(int.from_bytes(data[1:3], 'big'), int.from_bytes(data[3:7], 'big'))
    if mux == RESP_SERIAL_NR:
        return SerialAnswer(int.from_bytes(data[1:5], 'big'))
    if mux == RESP_RESET_ERR_LOG:
        return ResetAnswer(int.from_bytes(data[1:3], 'big'), int.from_bytes(data[3:7], 'big'))
    if mux in (RESP_MEAS_ERROR, RESP_SYSTEM_ERROR):
        return ErrorAnswer(mux == RESP_SYSTEM_ERROR, data[1], int.from_bytes(data[2:4], 'big'))
    if mux == RESP_WRONG_COMMAND:
        return WrongCommand(data[1])
    return OtherAnswer(mux, bytes(data))


def decode_config(arbitration_id: int, data: bytes) -> ResultConfig:
    """Decode the configuration layout of 0x2n (command) / 0xAn (answer)."""
    mode = data[1] & MODE_MASK
    if mode > TriggerMode.CYCLIC:  # 3 is not defined
        raise MalformedFrameError(arbitration_id, data, f'trigger mode {mode} (allowed 0..2)')
    return ResultConfig(IvtMux(data[0] & 0x07), TriggerMode(mode),
                        int.from_bytes(data[2:4], 'big'), bool(data[1] & ENDIANESS_BIT),
                        bool(data[1] & SIGN_BIT))


def decode_command(data: bytes) -> tuple[int, bytes]:
    """Split a 0x411 frame into (mux, data) for the simulator; MalformedFrameError if not 8."""
    if len(data) != DLC:
        raise MalformedFrameError(COMMAND_ID, data, f'DLC {len(data)}, expected {DLC}')
    return data[0], bytes(data)


def encode_answer(answer: IvtAnswer) -> Frame:
    """Build a 0x511 frame (the simulator's side)."""
    if isinstance(answer, ResultConfig):
        command = set_config(answer)
        data = bytes([RESP_CONFIG_RESULT + int(answer.kind)]) + command.data[1:]
    elif isinstance(answer, ModeAnswer):
        data = bytes([RESP_MODE, int(answer.running), int(answer.startup_running)])
    elif isinstance(answer, StoreAnswer):
        data = bytes([RESP_STORE])
    elif isinstance(answer, AliveAnswer):
        data = (bytes([RESP_ALIVE]) + answer.command_id.to_bytes(2, 'big')
                + _u32(answer.serial, 'IVT-S serial number'))
    elif isinstance(answer, SerialAnswer):
        data = bytes([RESP_SERIAL_NR]) + _u32(answer.serial, 'IVT-S serial number')
    elif isinstance(answer, ResetAnswer):
        data = (bytes([RESP_RESET_ERR_LOG]) + answer.item.to_bytes(2, 'big')
                + _u32(answer.serial, 'IVT-S serial number'))
    elif isinstance(answer, ErrorAnswer):
        data = (bytes([RESP_SYSTEM_ERROR if answer.system else RESP_MEAS_ERROR, answer.item])
                + answer.count_mask.to_bytes(2, 'big'))
    elif isinstance(answer, WrongCommand):
        data = bytes([RESP_WRONG_COMMAND, answer.command])
    else:
        data = answer.data
    return Frame(RESPONSE_ID, data + bytes(DLC - len(data)), False)
