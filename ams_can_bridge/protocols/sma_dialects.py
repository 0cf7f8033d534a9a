# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The SMA protocol's dialects (Pylontech, Victron): frames sent next to, or instead of, 0x35A.

doc/protocols.md section 5.4 holds the frames, their public sources, the accepted DLCs
and the decisions. ``DIALECTS`` states each frame once, as sma.MESSAGES does the SMA ones
(checked against msg_defs/sma.dbc by sma.check_dbc, run by sma.SmaCodec). Here too is what
the whole family shares: ``Message``, ``sma_field``, the ASCII helpers and ``pad_unsent``.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Callable, Union

from ams_can_bridge.errors import EncodeRangeError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.layout import BadValue, check_value, Layout, LITTLE, Signal

# Pylontech
PYLONTECH_KEEPALIVE_ID = 0x305  # inverter -> BMS, "every second", 8 zero bytes
PYLONTECH_ALARMS_ID = 0x359
PYLONTECH_REQUEST_ID = 0x35C
# Victron
VICTRON_BMS_NAME1_ID = 0x370  # part 2: 0x371
VICTRON_MODULES_ID = 0x372
VICTRON_CELL_EXTREMES_ID = 0x373
VICTRON_MIN_VOLTAGE_CELL_ID = 0x374  # 0x374..0x377: the cell ids of CELL_ID_KINDS
VICTRON_ENERGY_ID = 0x378
VICTRON_INSTALLED_CAPACITY_ID = 0x379
VICTRON_PRODUCT_NAME_ID = 0x382
# 0x373 carries whole kelvin; public encoders add 273 (diyBMS victron_message_373), the
# bridge subtracts 273.15: the 0.15 K is below the 1 K step either way (section 5.4).
KELVIN_OFFSET = 273.15
MAX_TEMPERATURE_K = 473  # 199.85 degC: no battery cell reads hotter than 200 degC
MAX_CELL_V = 10.0  # no battery cell reads more
MAX_CELL_TEMPERATURE_C = 200.0

# 0x359: condition (SMA name, as msg_defs/sma.dbc names it) -> byte of the alarm, bit; the
# warning is the same bit two bytes on.
PYLONTECH_CONDITIONS = (
    ('high_voltage', 'OverVoltage', 0, 1), ('low_voltage', 'UnderVoltage', 0, 2),
    ('high_temperature', 'OverTemperature', 0, 3),
    ('low_temperature', 'UnderTemperature', 0, 4),
    ('high_discharge_current', 'DischargeOverCurrent', 0, 7),
    ('high_charge_current', 'ChargeOverCurrent', 1, 0), ('bms_internal', 'BmsInternal', 1, 3),
)
PYLONTECH_CONDITION_NAMES = tuple(name for name, *_ in PYLONTECH_CONDITIONS)
# 0x35C byte 0, in PylontechRequest's order: the DBC's name and the bit.
PYLONTECH_REQUEST_BITS = (
    ('ChargeEnable', 7), ('DischargeEnable', 6),
    ('RequestChargeImmediately', 5),  # Pylontech: "force charge request I"
    ('ForceChargeRequestII', 4), ('FullChargeRequest', 3))
# 0x374..0x377 in ID order
CELL_ID_KINDS = ('min_voltage', 'max_voltage', 'min_temperature', 'max_temperature')


@dataclass(frozen=True)
class PylontechAlarms:
    """0x359: active alarms and warnings (SMA condition names) and the module count."""

    alarms: frozenset[str] = frozenset()
    warnings: frozenset[str] = frozenset()
    module_count: int | None = None

    @property
    def active_alarms(self) -> tuple[str, ...]:
        """Names of the active alarms, in bit order."""
        return tuple(n for n in PYLONTECH_CONDITION_NAMES if n in self.alarms)

    @property
    def active_warnings(self) -> tuple[str, ...]:
        """Names of the active warnings, in bit order."""
        return tuple(n for n in PYLONTECH_CONDITION_NAMES if n in self.warnings)


@dataclass(frozen=True)
class PylontechRequest:
    """0x35C: what the BMS allows and asks for."""

    charge_enable: bool
    discharge_enable: bool
    request_charge_immediately: bool = False
    force_charge_request_ii: bool = False
    full_charge_request: bool = False


@dataclass(frozen=True)
class VictronBmsName:
    """0x370 (part 1) / 0x371 (part 2): the BMS name, 8 ASCII characters each."""

    part: int
    text: str


@dataclass(frozen=True)
class PylontechCellExtremes:
    """0x370 as Pylontech V2 / Seplos send it (binary, not a name): degC and V."""

    max_temperature_c: float | None
    min_temperature_c: float | None
    max_cell_v: float | None
    min_cell_v: float | None


@dataclass(frozen=True)
class PylontechCellIds:
    """0x371 as Pylontech V2 / Seplos send it: the id of each extreme cell (module, cell)."""

    max_temperature_cell: int | None
    min_temperature_cell: int | None
    max_voltage_cell: int | None
    min_voltage_cell: int | None


@dataclass(frozen=True)
class VictronModules:
    """0x372: how many modules are OK, block charging, block discharging, are offline."""

    ok: int | None
    blocking_charge: int | None
    blocking_discharge: int | None
    offline: int | None


@dataclass(frozen=True)
class VictronCellExtremes:
    """0x373: lowest / highest cell voltage (V) and cell temperature (K on the wire)."""

    min_cell_v: float | None
    max_cell_v: float | None
    min_temperature_k: int | None
    max_temperature_k: int | None

    @property
    def min_temperature_c(self) -> float | None:
        """Lowest cell temperature in degC."""
        return _celsius(self.min_temperature_k)

    @property
    def max_temperature_c(self) -> float | None:
        """Highest cell temperature in degC."""
        return _celsius(self.max_temperature_k)


@dataclass(frozen=True)
class VictronCellId:
    """0x374..0x377: the ASCII id of the cell with the min/max voltage or temperature."""

    kind: str  # one of CELL_ID_KINDS
    text: str


@dataclass(frozen=True)
class VictronEnergy:
    """0x378: energy charged into and discharged from the battery over its life, kWh."""

    charged_kwh: float | None
    discharged_kwh: float | None


@dataclass(frozen=True)
class VictronInstalledCapacity:
    """0x379: installed capacity, Ah (diagnostics; BatteryState.capacity comes from 0x35F)."""

    capacity_ah: int | None


@dataclass(frozen=True)
class VictronProductName:
    """0x382: product (battery family) name, ASCII."""

    text: str


DialectReading = Union[PylontechAlarms, PylontechRequest, PylontechCellExtremes,
                       PylontechCellIds, VictronBmsName, VictronModules, VictronCellExtremes,
                       VictronCellId, VictronEnergy, VictronInstalledCapacity,
                       VictronProductName]


def _celsius(kelvin: int | None) -> float | None:
    return None if kelvin is None else round(kelvin - KELVIN_OFFSET, 2)


def is_text(data: bytes) -> bool:
    """Tell whether a frame is printable ASCII, once its NUL / space padding is dropped."""
    return all(0x20 <= b < 0x7F for b in bytes(data).rstrip(b'\x00 '))


def ascii_text(data: bytes) -> str:
    """Decode an ASCII field: padding (NUL, space) dropped, odd bytes as '?'."""
    text = bytes(data).rstrip(b'\x00 ')
    return ''.join(chr(b) if 0x20 <= b < 0x7F else '?' for b in text)


def encode_ascii(field: str, text: str) -> bytes:
    """Encode 1..8 printable ASCII characters, NUL-padded to 8 bytes; EncodeRangeError else."""
    if (not isinstance(text, str) or not 1 <= len(text) <= 8
            or not all(0x20 <= ord(c) < 0x7F for c in text)):
        raise EncodeRangeError(field, text, '1..8 printable ASCII chars')
    return text.encode('ascii').ljust(8, b'\x00')


# --- the dialects' frames, one row per ID (sma.SmaCodec runs them with the SMA frames') -------
def sma_field(name: str, start: int, length: int = 16, scale: float = 1, signed: bool = False,
              unit: str = '', field: str = '', **rules: Any) -> Signal:
    """
    Return a little-endian field of the SMA family (rules: low, high, check, lookup).

    A field with a name to send has the family's "not available" marker: all ones (0x8000
    signed), None both ways; errors name it 'sma.<field>'.
    """
    marker = (-(1 << length - 1) if signed else (1 << length) - 1) if field else None
    return Signal(name, start, length, LITTLE, signed, scale, 0, unit=unit,
                  field=f'sma.{field}', invalid=marker, **rules)


@dataclass(frozen=True)
class Message:
    """
    One frame of the SMA family: its reading, accepted DLCs (section 5.2) and bits.

    By default the reading is decoded and built by code generated from the layout, a frame
    cut short padded by pad_unsent first (pad=False: ``decode`` sees the DLC as sent).
    ``text``: an ASCII frame, the reading's values before the text in ``lead``, errors
    naming ``text``. ``decode`` / ``encode``: a rule a DBC cannot say.
    """

    reading: type
    dlcs: tuple[int, ...]
    layout: Layout
    text: str = ''
    lead: tuple = ()
    decode: Callable[[bytes], Any] | None = None
    encode: Callable[[Any], Frame] | None = None
    pad: bool = True
    dlc_note: str = ''  # why the other lengths are malformed, when the DLC alone does not say


def ascii_message(field: str, reading: type, name: str, *lead: Any,
                  decode: Callable[[bytes], Any] | None = None) -> Message:
    """Return an ASCII frame of 1..8 bytes; name: the DBC message's (its signal's after '_')."""
    return Message(reading, DLC_1_TO_8, Layout(name, 8, (sma_field(name.split('_')[1], 0, 64),)),
                   field, lead, decode=decode)


def _name_or_cells(part: int) -> Callable[[bytes], Any]:
    """
    Decode 0x370 / 0x371: Victron's BMS name, or Pylontech V2's binary cell extremes.

    Text when printable (section 5.4); else, with all 8 bytes, the binary layout when its
    values are possible; else the name with '?' for the odd bytes, as before.
    """
    decode_binary = _D_PYLON_EXTREMES if part == 1 else _D_PYLON_IDS

    def decode(data: bytes) -> Any:
        if len(data) == 8 and not is_text(data):
            try:
                reading = decode_binary(data)
            except BadValue:
                pass  # impossible as cell extremes: a name with odd bytes after all
            else:
                if part == 2 or _ordered(reading):
                    return reading
        return VictronBmsName(part, ascii_text(data))
    return decode


def _ordered(cells: PylontechCellExtremes) -> bool:
    pairs = ((cells.min_temperature_c, cells.max_temperature_c),
             (cells.min_cell_v, cells.max_cell_v))
    return all(low is None or high is None or low <= high for low, high in pairs)


def _installed_capacity(data: bytes) -> VictronInstalledCapacity:
    capacity = _D_CAPACITY(data)
    return VictronInstalledCapacity(None) if capacity.capacity_ah == 0 else capacity


def _pylontech_alarms(data: bytes) -> PylontechAlarms:
    *flags, count = _D_ALARMS(pad_unsent(data, DIALECTS[PYLONTECH_ALARMS_ID].layout))
    return PylontechAlarms(
        frozenset(n for n, on in zip(PYLONTECH_CONDITION_NAMES, flags) if on),
        frozenset(n for n, on in zip(PYLONTECH_CONDITION_NAMES, flags[7:]) if on),
        count if len(data) > 4 else None)  # DLC 4: the module count is not sent


def _cell_extremes(data: bytes) -> VictronCellExtremes:
    vmin, vmax, tmin, tmax = _D_RAW(data)  # mV and K, to compare as the BMS sent them
    if vmin is not None and vmax is not None and vmin > vmax:
        raise BadValue(f'min cell {vmin} mV above max cell {vmax} mV')
    if tmin is not None and tmax is not None and tmin > tmax:
        raise BadValue(f'min cell temperature {tmin} K above max {tmax} K')
    return _D_EXTREMES(data)


def encode_pylontech_alarms(message: PylontechAlarms) -> Frame:
    """0x359: the active conditions' bits, then the module count (DLC 4 if None)."""
    for kind in ('alarms', 'warnings'):
        unknown = set(getattr(message, kind)) - set(PYLONTECH_CONDITION_NAMES)
        if unknown:
            raise EncodeRangeError(f'sma.pylontech.{kind}', sorted(unknown),
                                   'condition names ' + ', '.join(PYLONTECH_CONDITION_NAMES))
    count = message.module_count
    if count is not None:
        count = check_value('sma.pylontech.module_count', count, 0, 255, integer=True)
    data = _E_ALARMS(*(int(name in names) for names in (message.alarms, message.warnings)
                       for name in PYLONTECH_CONDITION_NAMES), count or 0)
    return Frame(PYLONTECH_ALARMS_ID, data if count is not None else data[:4])


DLC_1_TO_8 = tuple(range(1, 9))
_TOO_HOT = 'cell temperature {value} K is above {high:g} K (200 degC)'
_CELL_V = 'cell voltage {value:g} V is above {high:g} V'
_CELL_C = 'cell temperature {value:g} degC is outside {low:g}..{high:g} degC'
# 0x370 / 0x371 as Pylontech V2 and Seplos send them (bms-to-inverter's Seplos and Pylon
# CAN readers; an Eco-Worthy capture): not in msg_defs/sma.dbc, whose 0x370 / 0x371 are
# Victron's name (one ID, two layouts: the content tells, _name_or_cells).
PYLONTECH_EXTREMES = Layout('Pylontech_CellExtremes', 8, tuple(
    sma_field(f'{end}CellTemperature', start, scale=0.1, signed=True, unit='degC',
              field=f'pylontech.{end.lower()}_temperature_c', low=-273.15,
              high=MAX_CELL_TEMPERATURE_C, check=_CELL_C)
    for end, start in (('Max', 0), ('Min', 16))) + tuple(
    sma_field(f'{end}CellVoltage', start, scale=0.001, unit='V',
              field=f'pylontech.{end.lower()}_cell_v', high=MAX_CELL_V, check=_CELL_V)
    for end, start in (('Max', 32), ('Min', 48))), divide=True)
PYLONTECH_IDS = Layout('Pylontech_CellIds', 8, tuple(
    sma_field(f'{name}Cell', 16 * k, field=f'pylontech.{field}_cell')
    for k, (name, field) in enumerate((
        ('MaxTemperature', 'max_temperature'), ('MinTemperature', 'min_temperature'),
        ('MaxVoltage', 'max_voltage'), ('MinVoltage', 'min_voltage')))))
_D_PYLON_EXTREMES = PYLONTECH_EXTREMES.decoder(into=PylontechCellExtremes)
_D_PYLON_IDS = PYLONTECH_IDS.decoder(into=PylontechCellIds)
DIALECTS = {
    # decoded from the frame as sent: DLC 4 says the module count is not sent
    PYLONTECH_ALARMS_ID: Message(PylontechAlarms, tuple(range(4, 9)), Layout(
        'Pylontech_AlarmsWarnings', 8, tuple(
            sma_field(f'{kind}_{dbc_name}', first + 8 * byte + bit, 1)
            for kind, first in (('Alarm', 0), ('Warning', 16))
            for _, dbc_name, byte, bit in PYLONTECH_CONDITIONS)
        + (sma_field('ModuleCount', 32, 8),)),
        decode=_pylontech_alarms, encode=encode_pylontech_alarms, pad=False),
    PYLONTECH_REQUEST_ID: Message(PylontechRequest, DLC_1_TO_8, Layout(
        'Pylontech_Request', 2, tuple(
            Signal(name, bit, 1, LITTLE, field=f'sma.pylontech.{field.name}', flag=True)
            for (name, bit), field in zip(PYLONTECH_REQUEST_BITS, fields(PylontechRequest))))),
    **{VICTRON_BMS_NAME1_ID + part - 1: ascii_message(
        'sma.victron.bms_name', VictronBmsName, f'Victron_BmsName{part}', part,
        decode=_name_or_cells(part))
       for part in (1, 2)},
    # odd DLCs would split a count
    VICTRON_MODULES_ID: Message(VictronModules, (2, 4, 6, 8), Layout('Victron_Modules', 8, tuple(
        sma_field(f'NumberOfModules{name}', 16 * k, field=f'victron.modules_{field}')
        for k, (name, field) in enumerate((
            ('Ok', 'ok'), ('BlockingCharge', 'blocking_charge'),
            ('BlockingDischarge', 'blocking_discharge'), ('Offline', 'offline')))))),
    VICTRON_CELL_EXTREMES_ID: Message(VictronCellExtremes, (8,), Layout(
        'Victron_CellExtremes', 8, (
            sma_field('MinCellVoltage', 0, 16, 0.001, unit='V', field='victron.min_cell_v',
                      high=MAX_CELL_V, check=_CELL_V),
            sma_field('MaxCellVoltage', 16, 16, 0.001, unit='V', field='victron.max_cell_v',
                      high=MAX_CELL_V, check=_CELL_V),
            sma_field('LowestCellTemperature', 32, unit='K', field='victron.min_temperature_k',
                      high=MAX_TEMPERATURE_K, check=_TOO_HOT),
            sma_field('HighestCellTemperature', 48, unit='K', field='victron.max_temperature_k',
                      high=MAX_TEMPERATURE_K, check=_TOO_HOT)), divide=True),
        decode=_cell_extremes,
        dlc_note='min/max cell voltage and temperature are 8 bytes (a Discover Lynx II '
                 'sends 4 that are not this layout)'),
    **{VICTRON_MIN_VOLTAGE_CELL_ID + k: ascii_message(
        'sma.victron.cell_id', VictronCellId, f'Victron_{name}CellId', kind)
       for k, (name, kind) in enumerate(zip(
           ('MinVoltage', 'MaxVoltage', 'MinTemperature', 'MaxTemperature'), CELL_ID_KINDS))},
    VICTRON_ENERGY_ID: Message(VictronEnergy, tuple(range(4, 9)), Layout('Victron_Energy', 8, (
        sma_field('ChargedEnergy', 0, 32, 0.1, unit='kWh', field='victron.charged_kwh'),
        sma_field('DischargedEnergy', 32, 32, 0.1, unit='kWh',
                  field='victron.discharged_kwh')), divide=True)),
    VICTRON_INSTALLED_CAPACITY_ID: Message(VictronInstalledCapacity, tuple(range(2, 9)), Layout(
        'Victron_InstalledCapacity', 2, (sma_field(
            'InstalledCapacity', 0, unit='Ah', field='victron.installed_capacity_ah'),)),
        decode=_installed_capacity),
    VICTRON_PRODUCT_NAME_ID: ascii_message('sma.victron.product_name', VictronProductName,
                                           'Victron_ProductName'),
}
DIALECT_IDS = frozenset(DIALECTS)  # Pylontech's 0x359, 0x35C; Victron's 0x370..0x382
_D_ALARMS = DIALECTS[PYLONTECH_ALARMS_ID].layout.decoder()
_E_ALARMS = DIALECTS[PYLONTECH_ALARMS_ID].layout.encoder()  # alarms, warnings, module count
_D_RAW = DIALECTS[VICTRON_CELL_EXTREMES_ID].layout.decoder(raw=True)
_D_CAPACITY = DIALECTS[VICTRON_INSTALLED_CAPACITY_ID].layout.decoder(
    into=VictronInstalledCapacity)
_D_EXTREMES: Callable[[bytes], VictronCellExtremes] = DIALECTS[
    VICTRON_CELL_EXTREMES_ID].layout.decoder(into=VictronCellExtremes)


def pad_unsent(data: bytes, layout: Layout) -> bytes:
    """
    Pad a frame cut short with 0xFF: the fields not sent read as "not available".

    A field sent in part is not sent: its bytes are dropped first, or ``378 40 08 00 00 2B``
    (DLC 5) would read 0xFFFFFF2B as the discharged energy (doc/protocols.md section 5.2).
    """
    sent = len(data)
    if sent >= layout.length:
        return data
    for s in layout.signals:  # every SMA field is little-endian: bytes first..last
        first, last = s.start // 8, (s.start + s.length - 1) // 8
        if first < sent <= last:
            sent = first
    return bytes(data[:sent]) + b'\xff' * (layout.length - sent)


# --- encode (simulator, tests; the bridge's keep-alive) ---------------------------------------
def keepalive_frame() -> Frame:
    """Build the inverter's keep-alive 0x305: eight zero bytes (Pylontech CAN protocol)."""
    return Frame(PYLONTECH_KEEPALIVE_ID, bytes(8))
