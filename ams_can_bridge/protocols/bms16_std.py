# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA BMS16 in its standard form: the EVMS3 protocol, 29-bit, 250 kbit/s.

doc/protocols.md section 6 holds the frames and setting slots a BMS16 fills, its marker, the
order of a write and their sources. The frames are the EVMS3's (``protocols.evms3``); the
settings are the EVMS3's rows under BMS16 names, plus the slots a BMS16 reassigns.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Mapping

from ams_can_bridge.errors import (
    BadConfigBytes, ConfigError, EncodeRangeError, MalformedFrameError)
from ams_can_bridge.protocols.bms12 import BMS12_BASE_ID
from ams_can_bridge.protocols.bms16 import SHUNT_SIZES_A  # slot 7: code 0..3
from ams_can_bridge.protocols.common import CELL_V_MAX, ConfigField, Frame
from ams_can_bridge.protocols.evms3 import (
    AcknowledgeError, BatteryCurrent, Bms12Cells, BMS16_MARKER, CELL_NUMBERS, CONFIG1,
    Evms3Codec, Evms3Error, Evms3State, generated, LAYOUTS, payload, PowerOff, ResetSoc, STATUS)
from ams_can_bridge.protocols.evms3_config import (
    balance_byte, BALANCE_FIELDS, BALANCE_ROW, balance_values, check_setting, CONFIG_LAYOUTS)
from ams_can_bridge.protocols.layout import Layout, Signal
from ams_can_bridge.protocols.settings import setting, Settings

DEFAULT_BASE_ID = 30                  # Common.h CAN_BASE_ID
CAN_CURRENT_SENSOR_ID = 40            # Common.h: a fixed ID, not base-relative
ID_COUNT = 10                         # base_id + 0 .. base_id + 9 (the EVMS3 offsets)
MAX_CELLS = 16
CELLS_PER_MODULE = 8                  # reply 1 and 2 of a BMS12 frame set: 4 + 4 cells
# BMS12 frames the BMS16 sends: (module, type) -> first cell (0-based) of the 4 in the frame
CELL_FRAMES = {(0, 1): 0, (0, 2): 4, (1, 1): 8, (1, 2): 12}
CELL_IDS = {BMS12_BASE_ID + 10 * m + t: first for (m, t), first in CELL_FRAMES.items()}
CONFIG_GAP_S = 0.02                   # the Monitor waits 20 ms after each settings frame
SLOTS = 32                            # setting bytes in IDs 32..35
MAX_PACK_V = MAX_CELLS * CELL_V_MAX   # 160 V: no pack of a BMS16 holds more


# ID 30 has the EVMS3 layout (protocols.evms3.LAYOUTS, checked against its DBC); byte 5 (aux
# voltage on an EVMS3) must be the marker, byte 6 (isolation) is unused.
_D_STATUS = generated(LAYOUTS['EVMS3_Status'].replace(
    'AuxVoltage', scale=1, low=BMS16_MARKER, check='byte 5 = {value}, not the BMS16 marker '
    '255: the status of another device (an EVMS3 sends its aux voltage there), not decoded')
    .replace('BatteryVoltage', high=MAX_PACK_V,  # the 16 cells of a BMS16, none over 10 V
             check='pack voltage {value:g} V (allowed {low:g}..{high:g} V: 16 cells)'),
    lambda _marker, *values: Bms16StdStatus(*values),
    'AuxVoltage', 'State', 'ErrorCode', 'AmpHoursRemaining', 'BatteryVoltage', 'Temperature')
_E_STATUS = LAYOUTS['EVMS3_Status'].encoder(exact=False)  # telemetry: rounded to 0.1


@dataclass(frozen=True, slots=True)
class Bms16StdStatus:
    """ID 30 of a BMS16: state, error, remaining Ah, pack voltage, temperature."""

    state: Evms3State
    error: Evms3Error
    amp_hours_ah: float
    pack_voltage_v: float
    temperature_c: int | None  # None: no sensor (raw 0)


@dataclass(frozen=True, slots=True)
class Bms16StdSettings:
    """Slots of IDs 32..35 a BMS16 uses (physical units); every other slot is sent as 0."""

    pack_capacity_ah: int
    soc_warning_pct: int
    full_voltage_v: int
    warn_current_a: int
    trip_current_a: int
    cells: int
    shunt_size_a: int
    min_cell_v: float
    max_cell_v: float
    balance_mode: str
    balance_v: float | None  # used only when balance_mode is 'static'
    hysteresis_v: float
    min_temp_c: int
    max_temp_c: int
    max_charge_voltage_v: int
    max_charge_current_a: int
    stationary_mode: bool
    reverse_current_display: bool
    night_brightness: int


# The setting slots a BMS16 uses (doc/protocols.md section 6): the EVMS3's rows under BMS16
# names, and the slots it reassigns or whose range it narrows; every other byte is sent as 0.
_EVMS3 = {s.name: s for layout in CONFIG_LAYOUTS[:4] for s in layout.signals}


def _alike(name: str, field: str, description: str) -> Signal:
    """Return the EVMS3 setting row name (its slot, scale and range) under a BMS16 field."""
    return replace(_EVMS3[name], field=field, description=description)


_LAYOUTS = (
    Layout('BMS16_Std_Config1', 8, (
        _alike('PackCapacity', 'pack_capacity_ah', 'pack capacity'),
        _alike('SocWarning', 'soc_warning_pct', 'SoC below which the BMS16 warns'),
        setting('FullVoltage', 2, 'full_voltage_v', 5, 70, 'V',
                'pack voltage that counts as full'),
        _alike('WarnCurrent', 'warn_current_a', 'overcurrent warning threshold'),
        _alike('TripCurrent', 'trip_current_a', 'overcurrent shutdown threshold'),
        setting('NumCells', 6, 'cells', 8, 16, '',
                'number of cells in series (slot 6, NUM_CELLS)'),
        setting('ShuntSize', 7, 'shunt_size_a', 0, 500, 'A', 'current shunt size: 0 (no '
                'shunt), 100, 200 or 500 A (slot 7, SHUNT_SIZE)', lookup=SHUNT_SIZES_A))),
    Layout('BMS16_Std_Config2', 8, (
        _alike('BmsMinVoltage', 'min_cell_v', 'minimum cell voltage'),
        _alike('BmsMaxVoltage', 'max_cell_v', 'maximum cell voltage'), BALANCE_ROW)),
    Layout('BMS16_Std_Config3', 8, (
        _alike('BmsHysteresis', 'hysteresis_v', 'hysteresis on the cell voltage limits'),
        _alike('BmsMinTemp', 'min_temp_c', 'minimum temperature'),
        _alike('BmsMaxTemp', 'max_temp_c', 'maximum temperature'),
        setting('ChargeVoltage', 3, 'max_charge_voltage_v', 0, 70, 'V', 'charger voltage'),
        setting('ChargeCurrent', 4, 'max_charge_current_a', 0, 127, 'A',
                'charger current (bit 7 of its byte belongs to the charger voltage)'))),
    Layout('BMS16_Std_Config4', 8, (
        _alike('StationaryMode', 'stationary_mode', 'stationary (non-vehicle) mode'),
        _alike('ReverseCurrentDisplay', 'reverse_current_display',
               "the Monitor shows the current's sign reversed"),
        _alike('NightBrightness', 'night_brightness', "the Monitor's night brightness, x10 %"))))
SETTINGS = Settings(_LAYOUTS)
_FIELDS = {f.name: f for f in (*SETTINGS.fields(), *BALANCE_FIELDS)}
CONFIG_FIELDS: tuple[ConfigField, ...] = tuple(
    _FIELDS[name] for name in Bms16StdSettings.__dataclass_fields__)
CONFIG_FIELD = {f.name: f for f in CONFIG_FIELDS}


def check_config_value(name: str, value: Any) -> Any:
    """Validate one value (physical units) and return it normalized; EncodeRangeError if not."""
    return check_setting(SETTINGS, name, value)


def config_from_mapping(values: Mapping[str, Any]) -> Bms16StdSettings:
    """Build the configuration (values checked and normalized); balance_v only if static."""
    names = list(Bms16StdSettings.__dataclass_fields__)
    missing = [n for n in names if values.get(n) is None and n != 'balance_v']
    if missing:
        raise EncodeRangeError(missing[0], None, 'a value (unset: ' + ', '.join(missing) + ')')
    return Bms16StdSettings(**{n: None if values.get(n) is None  # type: ignore[arg-type]
                               else check_config_value(n, values[n]) for n in names})


def config_payloads(cfg: Bms16StdSettings) -> list[bytes]:
    """Return the payloads of IDs 32..35: 32 slots, the unused ones 0 (EncodeRangeError)."""
    raws = {BALANCE_ROW.name: balance_byte(cfg.balance_mode, cfg.balance_v)}
    return [SETTINGS.payload(k, cfg, raws) for k in range(4)]


def decode_config(payloads: list[bytes]) -> dict[str, Any]:
    """Read the four payloads of IDs 32..35 back into values; BadConfigBytes for a raw value."""
    slots = b''.join(payloads)
    if len(slots) != SLOTS:
        raise BadConfigBytes(f'{len(slots)} setting bytes, expected {SLOTS}')
    values: dict[str, Any] = {}
    for k in range(4):
        values.update(SETTINGS.decode(k, slots[8 * k:8 * k + 8], BadConfigBytes))
    values.update(balance_values(slots[8 + BALANCE_ROW.start // 8], BadConfigBytes))
    return values


class Bms16StdCodec:
    """Frames of a standard-form BMS16: its status, cells and current; its commands."""

    is_extended_id = True

    def __init__(self, base_id: int = DEFAULT_BASE_ID) -> None:
        """Use IDs base_id .. base_id + 9, 40 and 301, 302, 311, 312 (ValueError on overlap)."""
        if not 0 <= base_id <= 0x1FFFFFFF - (ID_COUNT - 1):
            raise ConfigError(f'base_id {base_id} outside 0..0x{0x1FFFFFFF - ID_COUNT + 1:X} '
                              '(29-bit IDs, 10 of them)')
        own = set(range(base_id, base_id + ID_COUNT))
        fixed = {CAN_CURRENT_SENSOR_ID} | set(CELL_IDS)
        if own & fixed:
            raise ConfigError(f'base_id {base_id}: IDs {base_id}..{base_id + ID_COUNT - 1} '
                              f'overlap the fixed IDs 40 (current) or 301..312 (cells)')
        self.base_id = base_id
        # An EVMS3 codec at its default base 30 reads the BMS12 frames of modules 0 and 1 and
        # the current sensor's fixed ID 40 (its base + 10).
        self._evms3 = Evms3Codec(bms12_modules=2)
        # received: the status, the cell frames and the current (the rest are sent to it)
        self._evms3_ids = frozenset({CAN_CURRENT_SENSOR_ID} | set(CELL_IDS))
        self.arbitration_ids = self._evms3_ids | {base_id + STATUS}

    # --- decode ---------------------------------------------------------------------------
    def decode(self, arbitration_id: int, data: bytes) -> Any:
        """Frame -> Bms16StdStatus / Bms12Cells / BatteryCurrent; MalformedFrameError if bad."""
        if arbitration_id == self.base_id + STATUS:
            return _D_STATUS(arbitration_id, data)  # the marker first, then state and error
        if arbitration_id in self._evms3_ids:
            return self._evms3.decode(arbitration_id, data)
        raise MalformedFrameError(arbitration_id, data, 'not an ID of this BMS16')

    # --- encode ---------------------------------------------------------------------------
    def _frame(self, offset: int, data: bytes) -> Frame:
        return Frame(self.base_id + offset, bytes(data), True)

    def config_frames(self, cfg: Bms16StdSettings) -> list[Frame]:
        """Build IDs 36, 32, 33, 34, 35 in the Monitor's order (EncodeRangeError before any)."""
        payloads = config_payloads(cfg)
        module1 = cfg.cells - CELLS_PER_MODULE  # the Monitor's split: 8 on module 0
        cell_numbers = bytes([CELLS_PER_MODULE | module1 << 4]) + bytes(7)
        return [self._frame(CELL_NUMBERS, cell_numbers)] + [
            self._frame(CONFIG1 + k, p) for k, p in enumerate(payloads)]

    def encode(self, msg: Any) -> Frame:
        """Command or (for the simulator) reading -> Frame; EncodeRangeError if out of range."""
        if isinstance(msg, (AcknowledgeError, ResetSoc, PowerOff)):  # the EVMS3's rows
            return self._frame(*payload(msg))
        if isinstance(msg, Bms16StdStatus):
            # The EVMS3 status layout (its rows check state and error): byte 5 the marker
            # (aux voltage 25.5 V), byte 6 unused.
            return self._frame(STATUS, _E_STATUS(
                msg.state, msg.error, msg.amp_hours_ah, msg.pack_voltage_v, BMS16_MARKER / 10,
                0, 0, msg.temperature_c))
        if isinstance(msg, (Bms12Cells, BatteryCurrent)):
            return self._evms3.encode(msg)
        raise EncodeRangeError('message', msg, 'a BMS16 (standard) message')
