"""
The SMA protocol's dialects: frames many SMA-speaking BMSs send next to (or instead of) 0x35A.

The facts (not in the seed documents; confirmed from public vendor firmware and
widely used open implementations of the Pylontech and Victron CAN protocols):

- Pylontech (and the many BMSs that copy it) send **0x359** instead of 0x35A: byte 0 alarms
  (bit 1 over-voltage, bit 2 under-voltage, bit 3 over-temperature, bit 4 under-temperature,
  bit 7 discharge over-current), byte 1 alarms (bit 0 charge over-current, bit 3 BMS
  internal), bytes 2 and 3 the same bits as warnings, byte 4 the module count; and **0x35C**
  byte 0: bit 7 charge enable, bit 6 discharge enable, bit 5 request to charge immediately
  (Pylontech's "force charge request I"), bit 4 force charge request II, bit 3 full charge
  request (docs/protocols.md section 5).
- Victron-compatible BMSs add **0x370/0x371** (BMS name, ASCII, 8 + 8 bytes), **0x372**
  (U16 LE: modules OK, blocking charge, blocking discharge, offline), **0x373** (U16 LE: min
  cell mV, max cell mV, min cell temperature K, max cell temperature K), **0x374..0x377**
  (ASCII ids of the min/max voltage cell and the min/max temperature cell), **0x378** (U32
  LE 0.1 kWh: energy charged, energy discharged), **0x379** (U16 LE installed capacity Ah)
  and **0x382** (product name, ASCII).

Decisions:

- The 0x359 conditions carry the SMA 0x35A names (``high_voltage`` for over-voltage, ...), so
  an alarm means the same to the device whichever dialect reported it. Bits the dialect does
  not define are ignored (copies of the Pylontech frame use them differently); 0x359 bytes
  after byte 4 and 0x35C bytes after byte 0 are not interpreted.
- Accepted DLCs: 0x359 4..8 (DLC 4: module count not sent, None), 0x35C 1..8, 0x372 2, 4,
  6 or 8 (Victron-style short frames: the counts not sent are None; an odd DLC would split
  one), 0x373 8, 0x378 4..8 (DLC < 8: discharged energy None), 0x379 2..8, the ASCII frames
  1..8. Anything else is malformed.
- 0xFFFF in a U16 field and 0xFFFFFFFF in a U32 field are "not available" (None), as in
  the SMA frames.
  A min cell voltage above the max one (or a min temperature above the max) is malformed, and
  so is a temperature above MAX_TEMPERATURE_K (3549 K = 3275.85 degC, inside the 3276.7 degC
  the SMA frames themselves can carry): such a value would reach BatteryState.temperature.
- ASCII: trailing NUL / space padding dropped, a non-printable byte becomes '?'.
"""
from __future__ import annotations

from dataclasses import astuple, dataclass, fields
from typing import Callable, Union

from ams_can_bridge.protocols.common import (
    check_dlc, EncodeRangeError, Frame, MalformedFrameError)
from ams_can_bridge.protocols.layout import check_value, Layout, LITTLE, Signal

# Pylontech
PYLONTECH_KEEPALIVE_ID = 0x305  # inverter -> BMS, "every second", 8 zero bytes
PYLONTECH_ALARMS_ID = 0x359
PYLONTECH_REQUEST_ID = 0x35C
# Victron
VICTRON_BMS_NAME1_ID = 0x370
VICTRON_BMS_NAME2_ID = 0x371
VICTRON_MODULES_ID = 0x372
VICTRON_CELL_EXTREMES_ID = 0x373
VICTRON_MIN_VOLTAGE_CELL_ID = 0x374
VICTRON_MAX_VOLTAGE_CELL_ID = 0x375
VICTRON_MIN_TEMPERATURE_CELL_ID = 0x376
VICTRON_MAX_TEMPERATURE_CELL_ID = 0x377
VICTRON_ENERGY_ID = 0x378
VICTRON_INSTALLED_CAPACITY_ID = 0x379
VICTRON_PRODUCT_NAME_ID = 0x382

PYLONTECH_IDS = frozenset({PYLONTECH_ALARMS_ID, PYLONTECH_REQUEST_ID})
VICTRON_IDS = frozenset(range(VICTRON_BMS_NAME1_ID, VICTRON_INSTALLED_CAPACITY_ID + 1)) | {
    VICTRON_PRODUCT_NAME_ID}
DIALECT_IDS = PYLONTECH_IDS | VICTRON_IDS
_ASCII_DLC = tuple(range(1, 9))
DIALECT_DLC = {
    PYLONTECH_ALARMS_ID: (4, 5, 6, 7, 8), PYLONTECH_REQUEST_ID: _ASCII_DLC,
    VICTRON_BMS_NAME1_ID: _ASCII_DLC, VICTRON_BMS_NAME2_ID: _ASCII_DLC,
    VICTRON_MODULES_ID: (2, 4, 6, 8), VICTRON_CELL_EXTREMES_ID: (8,),
    VICTRON_ENERGY_ID: tuple(range(4, 9)), VICTRON_INSTALLED_CAPACITY_ID: tuple(range(2, 9)),
    VICTRON_PRODUCT_NAME_ID: _ASCII_DLC,
    VICTRON_MIN_VOLTAGE_CELL_ID: _ASCII_DLC, VICTRON_MAX_VOLTAGE_CELL_ID: _ASCII_DLC,
    VICTRON_MIN_TEMPERATURE_CELL_ID: _ASCII_DLC, VICTRON_MAX_TEMPERATURE_CELL_ID: _ASCII_DLC,
}
INVALID_U16 = 0xFFFF
INVALID_U32 = 0xFFFFFFFF
KELVIN_OFFSET = 273.15
MAX_TEMPERATURE_K = 3549

# 0x359: condition -> (byte of the alarm, bit); the warning is the same bit two bytes on.
PYLONTECH_CONDITIONS = (
    ('high_voltage', 0, 1), ('low_voltage', 0, 2), ('high_temperature', 0, 3),
    ('low_temperature', 0, 4), ('high_discharge_current', 0, 7),
    ('high_charge_current', 1, 0), ('bms_internal', 1, 3),
)
PYLONTECH_CONDITION_NAMES = tuple(name for name, _, _ in PYLONTECH_CONDITIONS)
CHARGE_ENABLE_BIT = 7
DISCHARGE_ENABLE_BIT = 6
REQUEST_CHARGE_IMMEDIATELY_BIT = 5  # Pylontech: "force charge request I"
FORCE_CHARGE_REQUEST_II_BIT = 4
FULL_CHARGE_REQUEST_BIT = 3
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


DialectReading = Union[PylontechAlarms, PylontechRequest, VictronBmsName, VictronModules,
                       VictronCellExtremes, VictronCellId, VictronEnergy,
                       VictronInstalledCapacity, VictronProductName]


def _celsius(kelvin: int | None) -> float | None:
    return None if kelvin is None else round(kelvin - KELVIN_OFFSET, 2)


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


# --- decode ------------------------------------------------------------------------------------
def _pylontech_alarms(aid: int, data: bytes) -> PylontechAlarms:
    alarms = frozenset(n for n, byte, bit in PYLONTECH_CONDITIONS if data[byte] >> bit & 1)
    warnings = frozenset(n for n, byte, bit in PYLONTECH_CONDITIONS
                         if data[byte + 2] >> bit & 1)
    return PylontechAlarms(alarms, warnings, data[4] if len(data) > 4 else None)


def _pylontech_request(aid: int, data: bytes) -> PylontechRequest:
    return _D_REQUEST(data)


def _bms_name(aid: int, data: bytes) -> VictronBmsName:
    return VictronBmsName(aid - VICTRON_BMS_NAME1_ID + 1, ascii_text(data))


def _modules(aid: int, data: bytes) -> VictronModules:
    return VictronModules(*_D[VICTRON_MODULES_ID](pad_unsent(data, 8)))


def _cell_extremes(aid: int, data: bytes) -> VictronCellExtremes:
    vmin, vmax, tmin, tmax = _D_RAW(data)
    if vmin is not None and vmax is not None and vmin > vmax:
        raise MalformedFrameError(aid, data, f'min cell {vmin} mV above max cell {vmax} mV')
    if tmin is not None and tmax is not None and tmin > tmax:
        raise MalformedFrameError(aid, data, f'min cell temperature {tmin} K above max {tmax} K')
    for kelvin in (tmin, tmax):
        if kelvin is not None and kelvin > MAX_TEMPERATURE_K:
            raise MalformedFrameError(aid, data, f'cell temperature {kelvin} K is above '
                                      f'{MAX_TEMPERATURE_K} K')
    return VictronCellExtremes(*_D[VICTRON_CELL_EXTREMES_ID](data))


def _cell_id(aid: int, data: bytes) -> VictronCellId:
    return VictronCellId(CELL_ID_KINDS[aid - VICTRON_MIN_VOLTAGE_CELL_ID], ascii_text(data))


def _energy(aid: int, data: bytes) -> VictronEnergy:
    return VictronEnergy(*_D[VICTRON_ENERGY_ID](pad_unsent(data, 8)))


def _installed_capacity(aid: int, data: bytes) -> VictronInstalledCapacity:
    return VictronInstalledCapacity(*_D[VICTRON_INSTALLED_CAPACITY_ID](data))


def _product_name(aid: int, data: bytes) -> VictronProductName:
    return VictronProductName(ascii_text(data))


DIALECT_DECODERS: dict[int, Callable[[int, bytes], DialectReading]] = {
    PYLONTECH_ALARMS_ID: _pylontech_alarms, PYLONTECH_REQUEST_ID: _pylontech_request,
    VICTRON_BMS_NAME1_ID: _bms_name, VICTRON_BMS_NAME2_ID: _bms_name,
    VICTRON_MODULES_ID: _modules, VICTRON_CELL_EXTREMES_ID: _cell_extremes,
    **{i: _cell_id for i in range(VICTRON_MIN_VOLTAGE_CELL_ID,
                                  VICTRON_MAX_TEMPERATURE_CELL_ID + 1)},
    VICTRON_ENERGY_ID: _energy, VICTRON_INSTALLED_CAPACITY_ID: _installed_capacity,
    VICTRON_PRODUCT_NAME_ID: _product_name,
}


# --- the wire layout of the dialects' frames (checked against msg_defs/sma.dbc by sma.py) ---
_PYLONTECH_DBC_NAMES = {
    'high_voltage': 'OverVoltage', 'low_voltage': 'UnderVoltage',
    'high_temperature': 'OverTemperature', 'low_temperature': 'UnderTemperature',
    'high_discharge_current': 'DischargeOverCurrent',
    'high_charge_current': 'ChargeOverCurrent', 'bms_internal': 'BmsInternal'}


def _u(name: str, start: int, length: int, scale: float = 1, unit: str = '', field: str = '',
       high: float | None = None) -> Signal:
    """Return a field; one with a name to send has the family's "not available" marker."""
    marker = (1 << length) - 1 if field else None  # all ones
    return Signal(name, start, length, LITTLE, False, scale, 0, None, high, unit,
                  f'sma.victron.{field}', invalid=marker)


DIALECT_LAYOUTS = {
    PYLONTECH_ALARMS_ID: Layout('Pylontech_AlarmsWarnings', 8, tuple(
        _u(f'{kind}_{_PYLONTECH_DBC_NAMES[name]}', first + 8 * byte + bit, 1)
        for kind, first in (('Alarm', 0), ('Warning', 16))
        for name, byte, bit in PYLONTECH_CONDITIONS) + (_u('ModuleCount', 32, 8),)),
    PYLONTECH_REQUEST_ID: Layout('Pylontech_Request', 2, tuple(  # in PylontechRequest's order
        Signal(name, bit, 1, LITTLE, field=f'sma.pylontech.{field.name}', flag=True)
        for (name, bit), field in zip((
            ('ChargeEnable', CHARGE_ENABLE_BIT), ('DischargeEnable', DISCHARGE_ENABLE_BIT),
            ('RequestChargeImmediately', REQUEST_CHARGE_IMMEDIATELY_BIT),
            ('ForceChargeRequestII', FORCE_CHARGE_REQUEST_II_BIT),
            ('FullChargeRequest', FULL_CHARGE_REQUEST_BIT)), fields(PylontechRequest)))),
    VICTRON_BMS_NAME1_ID: Layout('Victron_BmsName1', 8, (_u('BmsName1', 0, 64),)),
    VICTRON_BMS_NAME2_ID: Layout('Victron_BmsName2', 8, (_u('BmsName2', 0, 64),)),
    VICTRON_MODULES_ID: Layout('Victron_Modules', 8, tuple(
        _u(f'NumberOfModules{name}', 16 * k, 16, field=f'modules_{field}')
        for k, (name, field) in enumerate((
            ('Ok', 'ok'), ('BlockingCharge', 'blocking_charge'),
            ('BlockingDischarge', 'blocking_discharge'), ('Offline', 'offline'))))),
    VICTRON_CELL_EXTREMES_ID: Layout('Victron_CellExtremes', 8, (
        _u('MinCellVoltage', 0, 16, 0.001, 'V', 'min_cell_v'),
        _u('MaxCellVoltage', 16, 16, 0.001, 'V', 'max_cell_v'),
        _u('LowestCellTemperature', 32, 16, 1, 'K', 'min_temperature_k', MAX_TEMPERATURE_K),
        _u('HighestCellTemperature', 48, 16, 1, 'K', 'max_temperature_k', MAX_TEMPERATURE_K)),
        divide=True),
    **{VICTRON_MIN_VOLTAGE_CELL_ID + k: Layout(f'Victron_{name}CellId', 8, (
        _u(f'{name}CellId', 0, 64),)) for k, name in enumerate(
            ('MinVoltage', 'MaxVoltage', 'MinTemperature', 'MaxTemperature'))},
    VICTRON_ENERGY_ID: Layout('Victron_Energy', 8, (
        _u('ChargedEnergy', 0, 32, 0.1, 'kWh', 'charged_kwh'),
        _u('DischargedEnergy', 32, 32, 0.1, 'kWh', 'discharged_kwh')), divide=True),
    VICTRON_INSTALLED_CAPACITY_ID: Layout('Victron_InstalledCapacity', 2, (
        _u('InstalledCapacity', 0, 16, 1, 'Ah', 'installed_capacity_ah'),)),
    VICTRON_PRODUCT_NAME_ID: Layout('Victron_ProductName', 8, (_u('ProductName', 0, 64),)),
}

# Victron frames with numbers: decoded and built by code generated from the table. Cut short
# (DLC range), the fields not sent read as not available (padded with 0xFF).
_NUMBERS = (VICTRON_MODULES_ID, VICTRON_CELL_EXTREMES_ID, VICTRON_ENERGY_ID,
            VICTRON_INSTALLED_CAPACITY_ID)
_D = {i: DIALECT_LAYOUTS[i].decoder() for i in _NUMBERS}
_D_RAW = DIALECT_LAYOUTS[VICTRON_CELL_EXTREMES_ID].decoder(raw=True)  # mV, K to compare
_E = {i: DIALECT_LAYOUTS[i].encoder(exact=False) for i in _NUMBERS}
_E_ALARMS = DIALECT_LAYOUTS[PYLONTECH_ALARMS_ID].encoder()  # alarms, warnings, module count
_D_REQUEST = DIALECT_LAYOUTS[PYLONTECH_REQUEST_ID].decoder(into=PylontechRequest)
_E_REQUEST = DIALECT_LAYOUTS[PYLONTECH_REQUEST_ID].encoder()


def pad_unsent(data: bytes, length: int) -> bytes:
    """Pad a frame cut short with 0xFF: the fields not sent read as "not available"."""
    return data if len(data) >= length else bytes(data) + b'\xff' * (length - len(data))


def decode_dialect(arbitration_id: int, data: bytes) -> DialectReading:
    """Decode one dialect frame; MalformedFrameError for a DLC or value out of range."""
    decoder = DIALECT_DECODERS.get(arbitration_id)
    if decoder is None:
        raise MalformedFrameError(arbitration_id, data, 'not a Pylontech / Victron ID')
    check_dlc(arbitration_id, data, DIALECT_DLC[arbitration_id])
    return decoder(arbitration_id, data)


# --- encode (simulator, tests; the bridge's keep-alive) ---------------------------------------
def keepalive_frame() -> Frame:
    """Build the inverter's keep-alive 0x305: eight zero bytes (Pylontech CAN protocol)."""
    return Frame(PYLONTECH_KEEPALIVE_ID, bytes(8))


def _names(field: str, names: frozenset[str]) -> frozenset[str]:
    unknown = set(names) - set(PYLONTECH_CONDITION_NAMES)
    if unknown:
        raise EncodeRangeError(field, sorted(unknown),
                               'condition names ' + ', '.join(PYLONTECH_CONDITION_NAMES))
    return frozenset(names)


_ENCODED = {VictronModules: VICTRON_MODULES_ID, VictronCellExtremes: VICTRON_CELL_EXTREMES_ID,
            VictronEnergy: VICTRON_ENERGY_ID,
            VictronInstalledCapacity: VICTRON_INSTALLED_CAPACITY_ID}


def encode_dialect(message: DialectReading) -> Frame:
    """Encode a dialect message; EncodeRangeError names what the wire cannot carry."""
    if isinstance(message, PylontechAlarms):
        active = [_names(f'sma.pylontech.{kind}', getattr(message, kind))
                  for kind in ('alarms', 'warnings')]
        count = message.module_count
        if count is not None:
            count = check_value('sma.pylontech.module_count', count, 0, 255, integer=True)
        data = _E_ALARMS(*(int(name in names) for names in active
                           for name, _, _ in PYLONTECH_CONDITIONS), count or 0)
        return Frame(PYLONTECH_ALARMS_ID, data if count is not None else data[:4])
    if isinstance(message, PylontechRequest):
        return Frame(PYLONTECH_REQUEST_ID, _E_REQUEST(*astuple(message)))
    if isinstance(message, VictronBmsName):
        if message.part not in (1, 2):
            raise EncodeRangeError('sma.victron.bms_name.part', message.part, '1 or 2')
        return Frame(VICTRON_BMS_NAME1_ID + message.part - 1,
                     encode_ascii('sma.victron.bms_name', message.text))
    for cls, frame_id in _ENCODED.items():
        if isinstance(message, cls):
            return Frame(frame_id, _E[frame_id](*astuple(message)))
    if isinstance(message, VictronCellId):
        if message.kind not in CELL_ID_KINDS:
            raise EncodeRangeError('sma.victron.cell_id.kind', message.kind,
                                   'one of ' + ', '.join(CELL_ID_KINDS))
        return Frame(VICTRON_MIN_VOLTAGE_CELL_ID + CELL_ID_KINDS.index(message.kind),
                     encode_ascii(f'sma.victron.{message.kind}_cell_id', message.text))
    if isinstance(message, VictronProductName):
        return Frame(VICTRON_PRODUCT_NAME_ID,
                     encode_ascii('sma.victron.product_name', message.text))
    raise EncodeRangeError('message', message, 'an SMA, Pylontech or Victron message')
