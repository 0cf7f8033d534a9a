# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA BMS16, 11-bit / 500 kbit/s inverter form: frames <-> typed readings.

doc/protocols.md section 4 holds the frames, codes, source and decisions. The bits are
``LAYOUTS``, checked against msg_defs/bms16.dbc at the first codec; the configuration rows
carry each setting's range, step, unit and description (protocols/settings.py); this module
adds the 9th bits of the cells. The SMA frames a BMS16 also sends are ``protocols.sma``'s.
"""
from __future__ import annotations

import enum
import functools
from dataclasses import astuple, dataclass
from typing import Callable, Union

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import check_dlc, ConfigField, Frame, load_dbc
from ams_can_bridge.protocols.layout import BadValue, check_value, Layout, LITTLE, Signal
from ams_can_bridge.protocols.settings import setting, Settings

DEFAULT_BASE_ID = 500
STATUS, CELLS_1, CELLS_2, CELLS_3, CONFIG_1, CONFIG_2, ACK_ERROR, RESET_SOC, POWER_OFF = range(9)
ID_COUNT = 9
MAX_CELLS = 16
CELL_FRAME_FIRST = (0, 6, 12)  # first cell index (0-based) of the frames base + 1..3
CELL_FRAME_COUNT = (6, 6, 4)
SHUNT_SIZES_A = (0, 100, 200, 500)  # wire code 0..3
CELL_MAX_RAW = 500  # 5.00 V: the document's range of a cell (9 bits could carry 5.11 V)


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
class Bms16Settings(Bms16ConfigPart2, Bms16ConfigPart1):
    """The whole configuration: part 1's fields, then part 2's (``bms16.config.*``)."""


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
def _cell_frame(first: int, count: int) -> Layout:
    return Layout(f'BMS16_Cells_{first + 1}_{first + count}', 7, tuple(
        Signal(f'Cell{first + k + 1}_Low', 8 * k, 8, LITTLE) for k in range(count)) + (
        Signal('NinthBits', 48, 8, LITTLE),))


# The configuration frames: each byte a setting, with the range and step the BMS16 accepts
# (doc/protocols.md section 4); the ConfigFields and the checks come from these rows.
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
        Signal('Error', 0, 8, LITTLE, field='error', lookup=tuple(Bms16Error),
               check='error code {value}, known codes are {low}..{high}'),
        Signal('SoC', 8, 8, LITTLE, high=100, unit='%', field='soc_pct',
               check='SoC {value} %, above 100 %'),
        # the document's ranges (section 4): beyond them no BMS16 reading, malformed
        Signal('Voltage', 16, 16, LITTLE, scale=0.1, high=80, unit='V', field='voltage_v',
               check='pack voltage {value:g} V (allowed {low:g}..{high:g} V)'),
        Signal('Current', 32, 16, LITTLE, scale=0.1, offset=-3276.8, low=-1000, high=1000,
               unit='A', field='current_a',
               check='current {value:g} A (allowed {low:g}..{high:g} A)'),
        Signal('Temperature', 48, 8, LITTLE, high=120, unit='degC', field='temperature_c',
               check='temperature {value} degC (allowed {low:g}..{high:g} degC)')
    ), divide=True),
    *map(_cell_frame, CELL_FRAME_FIRST, CELL_FRAME_COUNT),
    _CONFIG_1, _CONFIG_2,
    *(Layout(f'BMS16_{name}', 0, ()) for name in ('AcknowledgeError', 'ResetSoc', 'PowerOff')),
)
_DLC = tuple(layout.length for layout in LAYOUTS)
# The readings sent as a whole frame, by offset from base_id (a cell frame is one of three)
_OFFSET = {Bms16Status: STATUS, Bms16ConfigPart1: CONFIG_1, Bms16ConfigPart2: CONFIG_2,
           AcknowledgeError: ACK_ERROR, ResetSoc: RESET_SOC, PowerOff: POWER_OFF}
_CLASS: dict[int, Callable[..., Bms16Reading]] = {offset: cls for cls, offset in _OFFSET.items()}
_COMMANDS = (ACK_ERROR, RESET_SOC, POWER_OFF)  # DLC 0
# Status and commands: their rows in the reading's order, one generated call each way;
# telemetry (the simulator's status) is rounded to the resolution.
_ENCODE = {offset: LAYOUTS[offset].encoder(exact=False) for offset in (STATUS, *_COMMANDS)}
_D_CELLS = tuple(layout.decoder() for layout in LAYOUTS[CELLS_1:CELLS_3 + 1])
_E_CELLS = tuple(layout.encoder() for layout in LAYOUTS[CELLS_1:CELLS_3 + 1])
_NINTH = tuple(tuple(256 * (bits >> k & 1) for k in range(8)) for bits in range(256))


def _cells(index: int, data: bytes) -> Bms16Cells:
    """Return cell frame index (0..2); the 9th bit of cell k is bit k of NinthBits."""
    *lows, ninth = _D_CELLS[index](data)  # a split the DBC cannot describe
    volts = tuple([(low + high) / 100 for low, high in zip(lows, _NINTH[ninth])])
    if max(volts) > CELL_MAX_RAW / 100:
        k = volts.index(max(volts))
        raise BadValue(f'cell {CELL_FRAME_FIRST[index] + k + 1} {volts[k]:g} V '
                       f'(allowed 0..{CELL_MAX_RAW / 100:g} V)')
    return Bms16Cells(CELL_FRAME_FIRST[index], volts)


def _config(k: int, data: bytes) -> Bms16Reading:
    """Return configuration part k + 1; a byte outside the BMS16's range is a BadValue."""
    return _CLASS[CONFIG_1 + k](**SETTINGS.decode(k, data, BadValue))


# data -> reading by offset; a refused value raises BadValue (the codec names the frame)
_DECODE: tuple[Callable[[bytes], Bms16Reading], ...] = (
    LAYOUTS[STATUS].decoder(into=Bms16Status),  # the error code and SoC are checked there
    *(functools.partial(_cells, index) for index in range(3)),
    *(functools.partial(_config, k) for k in range(2)),
    *(LAYOUTS[offset].decoder(into=_CLASS[offset]) for offset in _COMMANDS))


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
        self.base_id = base_id
        self.arbitration_ids = frozenset(range(base_id, base_id + ID_COUNT))

    # --- decode ---------------------------------------------------------------------
    def decode(self, arbitration_id: int, data: bytes) -> Bms16Reading:
        """Decode one frame; MalformedFrameError for a wrong DLC or an impossible value."""
        offset = arbitration_id - self.base_id
        if not 0 <= offset < ID_COUNT:
            raise MalformedFrameError(arbitration_id, data, 'not a BMS16 ID')
        if len(data) != _DLC[offset]:
            check_dlc(arbitration_id, data, _DLC[offset])
        try:
            return _DECODE[offset](data)
        except BadValue as exc:
            raise MalformedFrameError(arbitration_id, data, str(exc)) from None

    # --- encode ---------------------------------------------------------------------
    def frame(self, offset: int, data: bytes) -> Frame:
        """Build a frame at base_id + offset."""
        return Frame(self.base_id + offset, bytes(data), False)

    def encode(self, message: Bms16Reading) -> Frame:
        """Encode any BMS16 message; EncodeRangeError for a value the wire cannot carry."""
        if isinstance(message, Bms16Cells):
            return self._encode_cells(message)
        offset = _OFFSET.get(type(message))
        if offset is None:
            raise EncodeRangeError('message', message, 'a BMS16 message')
        if offset in (CONFIG_1, CONFIG_2):  # each value checked
            return self.frame(offset, SETTINGS.payload(offset - CONFIG_1, message))
        return self.frame(offset, _ENCODE[offset](*astuple(message)))

    def config_frames(self, config: Bms16Settings) -> list[Frame]:
        """Build the two configuration frames [base + 4, base + 5] (EncodeRangeError first)."""
        return [self.frame(CONFIG_1 + k, SETTINGS.payload(k, config)) for k in range(2)]

    def _encode_cells(self, cells: Bms16Cells) -> Frame:
        if cells.first_cell not in CELL_FRAME_FIRST:
            raise EncodeRangeError('first_cell', cells.first_cell, '0, 6 or 12')
        index = CELL_FRAME_FIRST.index(cells.first_cell)
        count = CELL_FRAME_COUNT[index]
        if len(cells.voltages_v) != count:
            raise EncodeRangeError(f'cells[{cells.first_cell}:].count',
                                   len(cells.voltages_v), f'exactly {count} voltages')
        raws = [round(check_value(f'cell{cells.first_cell + k + 1}_v', volts, 0,
                                  CELL_MAX_RAW / 100, unit='V') * 100)
                for k, volts in enumerate(cells.voltages_v)]
        ninth = sum((raw >> 8) << k for k, raw in enumerate(raws))  # as decoded above
        return self.frame(CELLS_1 + index, _E_CELLS[index](*(raw & 0xFF for raw in raws), ninth))
