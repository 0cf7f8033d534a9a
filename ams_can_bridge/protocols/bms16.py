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
- A configuration frame with a byte outside its documented range is malformed: the BMS16
  itself clamps such a value (the simulator too, through ``unchecked_config_values``), so
  the frame is not a configuration the bridge can trust. The encoder refuses any value
  outside a range or off its step with EncodeRangeError: nothing is clamped or rounded.
- Telemetry encoders (used by the simulator) round to the wire resolution and refuse what
  the wire cannot carry.

Speed: ``decode`` runs in the bus thread for every frame; its bits come from code generated
from ``LAYOUTS`` (protocols/layout.py), a table the codec checks against msg_defs/bms16.dbc
at construction. The configuration rows carry each setting's range, step, unit and
description (protocols/settings.py derives the fields and checks); the module adds the 9th
bits of the cells and the enum codes.
"""
from __future__ import annotations

import enum
import functools
from dataclasses import dataclass
from typing import Any, Callable, Union

from ams_can_bridge.protocols.common import (
    check_dlc, ConfigField, EncodeRangeError, Frame, load_dbc, MalformedFrameError)
from ams_can_bridge.protocols.layout import check_value, Layout, LITTLE, Signal
from ams_can_bridge.protocols.settings import setting, Settings

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


# --- the wire layout: one table, checked against msg_defs/bms16.dbc --------------------------
def _u(name: str, start: int, length: int = 8, scale: float = 1, offset: float = 0,
       unit: str = '', field: str = '') -> Signal:
    return Signal(name, start, length, LITTLE, False, scale, offset, unit=unit, field=field)


def _cell_frame(first: int, count: int) -> tuple[Signal, ...]:
    return tuple(_u(f'Cell{first + k + 1}_Low', 8 * k) for k in range(count)) + (
        _u('NinthBits', 48),)


# The configuration frames: each byte a setting, with the range and step the BMS16 accepts
# (docs/protocols.md section 4); the ConfigFields and the checks come from these rows.
_CONFIG_1 = Layout('BMS16_Config_1', 8, (
    setting('Cells', 0, 'cells', 12, 16, '', 'number of cells in series'),
    setting('PackCapacity', 1, 'pack_capacity_ah', 10, 1000, 'Ah', 'pack capacity', float, 10),
    setting('SocWarning', 2, 'soc_warning_pct', 0, 100, '%', 'SoC below which the BMS warns',
            float),
    setting('FullVoltage', 3, 'full_voltage_v', 0, 100, 'V',
            'pack voltage at which the pack counts as full (SoC reset to 100 %)', float),
    setting('WarnCurrent', 4, 'warn_current_a', 0, 1000, 'A', 'overcurrent warning threshold',
            float, 10),
    setting('TripCurrent', 5, 'trip_current_a', 0, 1000, 'A',
            'overcurrent shutdown threshold', float, 10),
    setting('TemperatureLimit', 6, 'temperature_limit_c', 0, 100, 'degC',
            'over-temperature limit', float),
    setting('MinCellVoltage', 7, 'min_cell_v', 1.0, 5.0, 'V',
            'minimum cell voltage (load disabled below)', float, 0.05)))
_CONFIG_2 = Layout('BMS16_Config_2', 4, (
    setting('MaxCellVoltage', 0, 'max_cell_v', 1.0, 5.0, 'V',
            'maximum cell voltage (charge disabled above)', float, 0.05),
    setting('Hysteresis', 1, 'hysteresis_v', 0.0, 1.0, 'V', 'hysteresis on cell voltage trips',
            float, 0.05),
    setting('BalanceVoltage', 2, 'balance_v', 1.0, 5.0, 'V', 'shunt balancing threshold voltage',
            float, 0.05),
    setting('ShuntSize', 3, 'shunt_size_a', 0, 500, 'A',
            'current shunt size: 0 (no shunt), 100, 200 or 500 A', lookup=SHUNT_SIZES_A)))


def _fault(s: Signal, raw: int, value: float | None) -> str:
    """Word a configuration byte outside the BMS16's range (its physical value)."""
    if s.lookup is not None:
        return f'shunt size code {raw}, known codes are 0..{len(s.lookup) - 1}'
    return f'{s.field} {value:g}, allowed {s.low:g}..{s.high:g}'


SETTINGS = Settings((_CONFIG_1, _CONFIG_2), _fault, ranged=False)
CONFIG_FIELDS: tuple[ConfigField, ...] = SETTINGS.fields()
CONFIG_FIELD = {f.name: f for f in CONFIG_FIELDS}
check_config_value = SETTINGS.check  # one value -> normalized (EncodeRangeError)

LAYOUTS: tuple[Layout, ...] = (  # by offset from base_id; divide: 523 -> 52.3 V exactly
    Layout('BMS16_Status', 7, (
        _u('Error', 0, field='error'), _u('SoC', 8, unit='%', field='soc_pct'),
        _u('Voltage', 16, 16, 0.1, unit='V', field='voltage_v'),
        _u('Current', 32, 16, 0.1, -3276.8, 'A', 'current_a'),
        _u('Temperature', 48, unit='degC', field='temperature_c')), divide=True),
    Layout('BMS16_Cells_1_6', 7, _cell_frame(0, 6)),
    Layout('BMS16_Cells_7_12', 7, _cell_frame(6, 6)),
    Layout('BMS16_Cells_13_16', 7, _cell_frame(12, 4)),
    _CONFIG_1, _CONFIG_2,
    Layout('BMS16_AcknowledgeError', 0, ()),
    Layout('BMS16_ResetSoc', 0, ()),
    Layout('BMS16_PowerOff', 0, ()),
)
_DLC = tuple(layout.length for layout in LAYOUTS)
_D_STATUS = LAYOUTS[STATUS].decoder()
_E_STATUS = LAYOUTS[STATUS].encoder(exact=False)  # telemetry: rounded to the resolution
_D_CELLS = tuple(layout.decoder() for layout in LAYOUTS[CELLS_1:CELLS_3 + 1])
_NINTH = tuple(tuple(256 * (bits >> k & 1) for k in range(8)) for bits in range(256))


def unchecked_config_values(data: bytes, part: int) -> dict[str, Any]:
    """Return the values of configuration frame 1 or 2 (part) as on the wire, unchecked."""
    return SETTINGS.decode(part - 1, data)


def _malformed(arbitration_id: int, data: bytes) -> Callable[[str], MalformedFrameError]:
    """Return fail(why) for a configuration byte outside the documented range."""
    return lambda why: MalformedFrameError(arbitration_id, data, why)


@functools.cache
def check_dbc() -> None:
    """Raise LayoutError unless msg_defs/bms16.dbc has the bits of LAYOUTS."""
    db = load_dbc('bms16')
    for offset, layout in enumerate(LAYOUTS):
        layout.check_dbc(db.get_message_by_frame_id(DEFAULT_BASE_ID + offset),
                         'msg_defs/bms16.dbc', 'BMS16')


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
                          self._config, self._config, self._command, self._command,
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
        code, soc, volts, amps, temp = _D_STATUS(data)
        if code >= len(_ERRORS):
            raise MalformedFrameError(arbitration_id, data,
                                      f'error code {code}, known codes are 0..8')
        if soc > 100:
            raise MalformedFrameError(arbitration_id, data, f'SoC {soc} %, above 100 %')
        return Bms16Status(_ERRORS[code], soc, volts, amps, temp)

    @staticmethod
    def _cells(arbitration_id: int, offset: int, data: bytes) -> Bms16Cells:
        index = offset - CELLS_1
        *lows, ninth = _D_CELLS[index](data)
        # The 9th bit of cell k is bit k of NinthBits (a split the DBC cannot describe).
        return Bms16Cells(CELL_FRAME_FIRST[index], tuple(
            [(low + high) / 100 for low, high in zip(lows, _NINTH[ninth])]))

    @staticmethod
    def _config(arbitration_id: int, offset: int, data: bytes) -> Bms16Reading:
        part = offset - CONFIG_1  # 0, 1: the frames of SETTINGS
        values = SETTINGS.decode(part, data, _malformed(arbitration_id, data))
        return (Bms16ConfigPart1, Bms16ConfigPart2)[part](**values)

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
            return self.frame(CONFIG_1, SETTINGS.payload(0, message))
        if isinstance(message, Bms16ConfigPart2):
            return self.frame(CONFIG_2, SETTINGS.payload(1, message))
        for offset, cls in ((ACK_ERROR, AcknowledgeError), (RESET_SOC, ResetSoc),
                            (POWER_OFF, PowerOff)):
            if isinstance(message, cls):
                return self.frame(offset, b'')
        raise EncodeRangeError('message', message, 'a BMS16 message')

    def config_frames(self, config: Bms16Config) -> list[Frame]:
        """Build the two configuration frames [base + 4, base + 5], validating every value."""
        for name in CONFIG_FIELD:  # every value checked before the first frame is built
            check_config_value(name, getattr(config, name))
        return [self.frame(CONFIG_1, SETTINGS.payload(0, config)),
                self.frame(CONFIG_2, SETTINGS.payload(1, config))]

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
        return self.frame(STATUS, _E_STATUS(
            check_value('error', status.error, 0, 8, integer=True), status.soc_pct,
            status.voltage_v, status.current_a, status.temperature_c))

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
            raw = round(check_value(f'cell{cells.first_cell + k + 1}_v', volts, 0, 5.11,
                                    unit='V') * 100)
            data[k] = raw & 0xFF
            data[6] |= (raw >> 8) << k
        return self.frame(CELLS_1 + index, bytes(data))
