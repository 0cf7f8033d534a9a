"""
ZEVA BMS16 (11-bit / 500 kbit/s variant): frames <-> typed readings (docs/protocols.md section 4).

Nine IDs from ``base_id`` (default 500 = 0x1F4), every multi-byte field little-endian:

- base + 0, status (4 Hz, DLC 7): error code, SoC %, voltage 0.1 V, current (raw - 32768,
  0.1 A, **positive = discharge**), temperature degC;
- base + 1..3, cell voltages (4 Hz, DLC 7): the low 8 bits of 6 cells (base + 3: 4 cells,
  13..16) in bytes 0..5 and their 9th bits in byte 6 (bit k = k-th cell of the frame);
  0.01 V per bit, so 9 bits reach 5.11 V;
- base + 4 / base + 5, configuration parts 1 and 2 (to the BMS16, DLC 8 / 4);
- base + 6 / 7 / 8: acknowledge error / reset SoC to 100 % / power off (DLC 0).

The BMS16 also sends the SMA Sunny Island frames 0x351.. at fixed IDs: those are decoded by
``protocols.sma.SmaCodec``; this codec knows only the BMS16's own IDs.

Decisions (where the vendor document is silent):

- Unused bits of a cell frame (byte 6 bits 4..7 and bytes 4..5 of the 13..16 frame, byte 6
  bits 6..7 of the others) are ignored, not malformed: the vendor does not say what the
  firmware puts there, and rejecting the frame would blank real cell readings for it.
- An error code above 8 or a shunt-size code above 3 is malformed (no such value exists).
- Configuration frames are decoded as sent (the BMS16 itself restricts received values to
  its ranges, the simulator does the same); the encoder instead refuses any value outside
  a range or off its step with EncodeRangeError: nothing is clamped or rounded.
- Telemetry encoders (used by the simulator) round to the wire resolution and refuse what
  the wire cannot carry.

Speed: ``decode`` runs in the bus thread for every frame, so it is hand-written with
``int.from_bytes``; the DBC (msg_defs/bms16.dbc) stays the reference, and the codec checks
at construction that it has the layout the fast path assumes.
"""
from __future__ import annotations

import enum
import functools
from dataclasses import dataclass, fields
from typing import Union

from ams_can_bridge.protocols.common import (
    check_dlc, check_range, ConfigField, EncodeRangeError, Frame, load_dbc,
    MalformedFrameError)

DEFAULT_BASE_ID = 500
STATUS, CELLS_1, CELLS_2, CELLS_3, CONFIG_1, CONFIG_2, ACK_ERROR, RESET_SOC, POWER_OFF = range(9)
ID_COUNT = 9
CURRENT_OFFSET = 32768
MAX_CELLS = 16
CELL_FRAME_FIRST = (0, 6, 12)  # first cell index (0-based) of the frames base + 1..3
CELL_FRAME_COUNT = (6, 6, 4)
SHUNT_SIZES_A = (0, 100, 200, 500)  # wire code 0..3


class Bms16Error(enum.IntEnum):
    """Error code in byte 0 of the status frame."""

    NONE = 0
    CORRUPT_EEPROM = 1
    LOAD_DISABLED_UNDERVOLTAGE = 2
    CHARGE_DISABLED_OVERVOLTAGE = 3
    LOW_SOC = 4
    OVERCURRENT_WARNING = 5
    OVERCURRENT_SHUTDOWN = 6
    OVERTEMPERATURE = 7
    CRITICAL_VOLTAGE = 8


# The vehicle may go on with these; every other non-zero code is an error.
BMS16_WARNINGS = frozenset({Bms16Error.LOW_SOC, Bms16Error.OVERCURRENT_WARNING})
_ERRORS = tuple(Bms16Error)


@dataclass(frozen=True)
class Bms16Status:
    """Status frame (base + 0); current_a has the wire sign: positive = discharge."""

    error: Bms16Error
    soc_pct: int
    voltage_v: float
    current_a: float
    temperature_c: int


@dataclass(frozen=True)
class Bms16Cells:
    """One cell frame: first_cell is 0, 6 or 12 (0-based); 6 voltages (4 in the last)."""

    first_cell: int
    voltages_v: tuple[float, ...]


@dataclass(frozen=True)
class Bms16ConfigPart1:
    """Configuration frame 1 (base + 4), physical units."""

    cells: int
    pack_capacity_ah: float
    soc_warning_pct: float
    full_voltage_v: float
    warn_current_a: float
    trip_current_a: float
    temperature_limit_c: float
    min_cell_v: float


@dataclass(frozen=True)
class Bms16ConfigPart2:
    """Configuration frame 2 (base + 5), physical units."""

    max_cell_v: float
    hysteresis_v: float
    balance_v: float
    shunt_size_a: int


@dataclass(frozen=True)
class Bms16Config:
    """The whole configuration (the names of the ``bms16.config.*`` parameters)."""

    cells: int
    pack_capacity_ah: float
    soc_warning_pct: float
    full_voltage_v: float
    warn_current_a: float
    trip_current_a: float
    temperature_limit_c: float
    min_cell_v: float
    max_cell_v: float
    hysteresis_v: float
    balance_v: float
    shunt_size_a: int


@dataclass(frozen=True)
class AcknowledgeError:
    """Command: acknowledge the current error (base + 6, no data)."""


@dataclass(frozen=True)
class ResetSoc:
    """Command: reset the SoC to 100 % (base + 7, no data)."""


@dataclass(frozen=True)
class PowerOff:
    """Command: power the BMS16 off (base + 8, no data)."""


Bms16Reading = Union[Bms16Status, Bms16Cells, Bms16ConfigPart1, Bms16ConfigPart2,
                     AcknowledgeError, ResetSoc, PowerOff]

CONFIG_FIELDS: tuple[ConfigField, ...] = (
    ConfigField('cells', int, 12, 16, 1, '', 'number of cells in series'),
    ConfigField('pack_capacity_ah', float, 10, 1000, 10, 'Ah', 'pack capacity'),
    ConfigField('soc_warning_pct', float, 0, 100, 1, '%', 'SoC below which the BMS warns'),
    ConfigField('full_voltage_v', float, 0, 100, 1, 'V',
                'pack voltage at which the pack counts as full (SoC reset to 100 %)'),
    ConfigField('warn_current_a', float, 0, 1000, 10, 'A', 'overcurrent warning threshold'),
    ConfigField('trip_current_a', float, 0, 1000, 10, 'A', 'overcurrent shutdown threshold'),
    ConfigField('temperature_limit_c', float, 0, 100, 1, 'degC', 'over-temperature limit'),
    ConfigField('min_cell_v', float, 1.0, 5.0, 0.05, 'V',
                'minimum cell voltage (load disabled below)'),
    ConfigField('max_cell_v', float, 1.0, 5.0, 0.05, 'V',
                'maximum cell voltage (charge disabled above)'),
    ConfigField('hysteresis_v', float, 0.0, 1.0, 0.05, 'V', 'hysteresis on cell voltage trips'),
    ConfigField('balance_v', float, 1.0, 5.0, 0.05, 'V', 'shunt balancing threshold voltage'),
    ConfigField('shunt_size_a', int, 0, 500, None, 'A',
                'current shunt size: 0 (no shunt), 100, 200 or 500 A'),
)
CONFIG_FIELD = {f.name: f for f in CONFIG_FIELDS}
# Physical units per wire count of each configuration byte (shunt size is an enum).
_CONFIG_SCALE = {
    'cells': 1, 'pack_capacity_ah': 10, 'soc_warning_pct': 1, 'full_voltage_v': 1,
    'warn_current_a': 10, 'trip_current_a': 10, 'temperature_limit_c': 1,
    'min_cell_v': 0.05, 'max_cell_v': 0.05, 'hysteresis_v': 0.05, 'balance_v': 0.05,
}
_PART1 = tuple(f.name for f in fields(Bms16ConfigPart1))
_PART2 = tuple(f.name for f in fields(Bms16ConfigPart2))


def check_config_value(name: str, value: object) -> int:
    """
    Validate one configuration value (physical units) and return its wire byte.

    Raises EncodeRangeError naming the field, the value and the allowed range for a value
    out of range, off its step, or not a number; nothing is clamped.
    """
    spec = CONFIG_FIELD[name]
    if name == 'shunt_size_a':
        allowed = '0 (no shunt), 100, 200 or 500 A'
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise EncodeRangeError(name, value, allowed)
        for code, size in enumerate(SHUNT_SIZES_A):
            if value == size:
                return code
        raise EncodeRangeError(name, value, allowed)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise EncodeRangeError(
            name, value,
            f'a number {spec.low:g}..{spec.high:g} {spec.unit}'.rstrip())
    check_range(name, value, spec.low, spec.high, spec.step, spec.unit)
    return round(value / _CONFIG_SCALE[name])


def _config_value(name: str, raw: int) -> float | int:
    """Physical value of a configuration byte (exact decimals: divide, do not multiply)."""
    if name == 'cells':
        return raw
    scale = _CONFIG_SCALE[name]
    return raw / 20 if scale == 0.05 else float(raw * scale)


def _checked_config_value(name: str, raw: int, arbitration_id: int, data: bytes) -> float | int:
    """
    Return the physical value; raise MalformedFrameError outside the documented range.

    The BMS16 itself clamps such a value (the simulator does: ``unchecked_config_values``);
    a frame seen on the bus with one is not a configuration the bridge can trust.
    """
    spec = CONFIG_FIELD[name]
    value = _config_value(name, raw)
    if not spec.low <= value <= spec.high:
        raise MalformedFrameError(arbitration_id, data,
                                  f'{name} {value:g}, allowed {spec.low:g}..{spec.high:g}')
    return value


def unchecked_config_values(data: bytes, part: int) -> dict[str, float | int]:
    """Return the values of configuration frame 1 or 2 (part) as on the wire, unchecked."""
    names = _PART1 if part == 1 else _PART2[:3]
    return {name: _config_value(name, raw) for name, raw in zip(names, data)}


# (message offset, signal name) -> (start bit, length, scale, offset, signed) as the fast
# path assumes; checked against the installed DBC once per process.
_DBC_LAYOUT = {
    (STATUS, 'Error'): (0, 8, 1, 0, False),
    (STATUS, 'SoC'): (8, 8, 1, 0, False),
    (STATUS, 'Voltage'): (16, 16, 0.1, 0, False),
    (STATUS, 'Current'): (32, 16, 0.1, -3276.8, False),
    (STATUS, 'Temperature'): (48, 8, 1, 0, False),
    (CELLS_1, 'Cell1_Low'): (0, 8, 1, 0, False),
    (CELLS_1, 'NinthBits'): (48, 8, 1, 0, False),
    (CELLS_3, 'Cell16_Low'): (24, 8, 1, 0, False),
    (CELLS_3, 'NinthBits'): (48, 8, 1, 0, False),
    (CONFIG_1, 'PackCapacity'): (8, 8, 10, 0, False),
    (CONFIG_1, 'MinCellVoltage'): (56, 8, 0.05, 0, False),
    (CONFIG_2, 'Hysteresis'): (8, 8, 0.05, 0, False),
    (CONFIG_2, 'ShuntSize'): (24, 8, 1, 0, False),
}
_DLC = (7, 7, 7, 7, 8, 4, 0, 0, 0)


@functools.cache
def check_dbc() -> None:
    """Raise RuntimeError unless msg_defs/bms16.dbc has the layout the codec assumes."""
    db = load_dbc('bms16')
    for offset, dlc in enumerate(_DLC):
        msg = db.get_message_by_frame_id(DEFAULT_BASE_ID + offset)
        if msg.length != dlc or msg.is_extended_frame:
            raise RuntimeError(f'bms16.dbc: message {DEFAULT_BASE_ID + offset} has DLC '
                               f'{msg.length}, the codec assumes {dlc}')
    for (offset, name), want in _DBC_LAYOUT.items():
        sig = db.get_message_by_frame_id(DEFAULT_BASE_ID + offset).get_signal_by_name(name)
        have = (sig.start, sig.length, sig.scale, sig.offset, sig.is_signed)
        if have != want or sig.byte_order != 'little_endian':
            raise RuntimeError(f'bms16.dbc: signal {name} is {have}, the codec assumes {want}')


class Bms16Codec:
    """Decode and encode the BMS16's own frames at ``base_id .. base_id + 8``."""

    is_extended_id = False

    def __init__(self, base_id: int = DEFAULT_BASE_ID) -> None:
        if not 0 <= base_id <= 0x7FF - (ID_COUNT - 1):
            raise EncodeRangeError('base_id', base_id,
                                   f'0..{0x7FF - (ID_COUNT - 1)} (11-bit IDs, 9 of them)')
        check_dbc()
        self.base_id = base_id
        self.arbitration_ids = frozenset(range(base_id, base_id + ID_COUNT))
        self._decoders = (self._status, self._cells, self._cells, self._cells,
                          self._config1, self._config2, self._command, self._command,
                          self._command)

    # --- decode ---------------------------------------------------------------------
    def decode(self, arbitration_id: int, data: bytes) -> Bms16Reading:
        """Decode one frame; MalformedFrameError for a wrong DLC or an impossible value."""
        offset = arbitration_id - self.base_id
        if not 0 <= offset < ID_COUNT:
            raise MalformedFrameError(arbitration_id, data, 'not a BMS16 ID')
        if len(data) != _DLC[offset]:
            check_dlc(arbitration_id, data, _DLC[offset])
        return self._decoders[offset](arbitration_id, offset, data)

    @staticmethod
    def _status(arbitration_id: int, offset: int, data: bytes) -> Bms16Status:
        code = data[0]
        if code >= len(_ERRORS):
            raise MalformedFrameError(arbitration_id, data,
                                      f'error code {code}, known codes are 0..8')
        if data[1] > 100:
            raise MalformedFrameError(arbitration_id, data, f'SoC {data[1]} %, above 100 %')
        return Bms16Status(
            error=_ERRORS[code], soc_pct=data[1],
            voltage_v=(data[2] | data[3] << 8) / 10,
            current_a=((data[4] | data[5] << 8) - CURRENT_OFFSET) / 10,
            temperature_c=data[6])

    @staticmethod
    def _cells(arbitration_id: int, offset: int, data: bytes) -> Bms16Cells:
        index = offset - CELLS_1
        ninth = data[6]
        return Bms16Cells(CELL_FRAME_FIRST[index], tuple(
            (data[k] | ((ninth >> k) & 1) << 8) / 100 for k in range(CELL_FRAME_COUNT[index])))

    @staticmethod
    def _config1(arbitration_id: int, offset: int, data: bytes) -> Bms16ConfigPart1:
        return Bms16ConfigPart1(*(_checked_config_value(n, raw, arbitration_id, data)
                                  for n, raw in zip(_PART1, data)))

    @staticmethod
    def _config2(arbitration_id: int, offset: int, data: bytes) -> Bms16ConfigPart2:
        if data[3] >= len(SHUNT_SIZES_A):
            raise MalformedFrameError(arbitration_id, data,
                                      f'shunt size code {data[3]}, known codes are 0..3')
        return Bms16ConfigPart2(*(_checked_config_value(n, raw, arbitration_id, data)
                                  for n, raw in zip(_PART2[:3], data)),
                                SHUNT_SIZES_A[data[3]])

    @staticmethod
    def _command(arbitration_id: int, offset: int, data: bytes) -> Bms16Reading:
        return (AcknowledgeError, ResetSoc, PowerOff)[offset - ACK_ERROR]()

    # --- encode ---------------------------------------------------------------------
    def frame(self, offset: int, data: bytes) -> Frame:
        """Build a frame at base_id + offset."""
        return Frame(self.base_id + offset, bytes(data), False)

    def encode(self, message: Bms16Reading) -> Frame:
        """Encode any BMS16 message; EncodeRangeError for a value the wire cannot carry."""
        if isinstance(message, Bms16Status):
            return self._encode_status(message)
        if isinstance(message, Bms16Cells):
            return self._encode_cells(message)
        if isinstance(message, Bms16ConfigPart1):
            return self.frame(CONFIG_1, bytes(
                check_config_value(n, getattr(message, n)) for n in _PART1))
        if isinstance(message, Bms16ConfigPart2):
            return self.frame(CONFIG_2, bytes(
                check_config_value(n, getattr(message, n)) for n in _PART2))
        for offset, cls in ((ACK_ERROR, AcknowledgeError), (RESET_SOC, ResetSoc),
                            (POWER_OFF, PowerOff)):
            if isinstance(message, cls):
                return self.frame(offset, b'')
        raise TypeError(f'not a BMS16 message: {message!r}')

    def config_frames(self, config: Bms16Config) -> list[Frame]:
        """Build the two configuration frames [base + 4, base + 5], validating every value."""
        values = {f.name: getattr(config, f.name) for f in fields(Bms16Config)}
        raw = {name: check_config_value(name, value) for name, value in values.items()}
        return [self.frame(CONFIG_1, bytes(raw[n] for n in _PART1)),
                self.frame(CONFIG_2, bytes(raw[n] for n in _PART2))]

    def acknowledge_error(self) -> Frame:
        """Frame base + 6 (acknowledge error)."""
        return self.encode(AcknowledgeError())

    def reset_soc(self) -> Frame:
        """Frame base + 7 (reset SoC to 100 %)."""
        return self.encode(ResetSoc())

    def power_off(self) -> Frame:
        """Frame base + 8 (power off)."""
        return self.encode(PowerOff())

    def _encode_status(self, status: Bms16Status) -> Frame:
        error = status.error
        check_range('error', error, 0, 8, 1)
        check_range('soc_pct', status.soc_pct, 0, 100)
        check_range('voltage_v', status.voltage_v, 0, 6553.5, unit='V')
        check_range('current_a', status.current_a, -3276.8, 3276.7, unit='A')
        check_range('temperature_c', status.temperature_c, 0, 255, unit='degC')
        volts = round(status.voltage_v * 10)
        amps = round(status.current_a * 10) + CURRENT_OFFSET
        return self.frame(STATUS, bytes((
            int(error), round(status.soc_pct), volts & 0xFF, volts >> 8, amps & 0xFF,
            amps >> 8, round(status.temperature_c))))

    def _encode_cells(self, cells: Bms16Cells) -> Frame:
        if cells.first_cell not in CELL_FRAME_FIRST:
            raise EncodeRangeError('first_cell', cells.first_cell, '0, 6 or 12')
        index = CELL_FRAME_FIRST.index(cells.first_cell)
        count = CELL_FRAME_COUNT[index]
        if len(cells.voltages_v) != count:
            raise EncodeRangeError(f'cells[{cells.first_cell}:].count',
                                   len(cells.voltages_v), f'exactly {count} voltages')
        data = bytearray(7)
        for k, volts in enumerate(cells.voltages_v):
            check_range(f'cell{cells.first_cell + k + 1}_v', volts, 0, 5.11, unit='V')
            raw = round(volts * 100)
            data[k] = raw & 0xFF
            data[6] |= (raw >> 8) << k
        return self.frame(CELLS_1 + index, bytes(data))
