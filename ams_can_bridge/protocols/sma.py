# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
SMA Sunny Island BMS protocol: frames <-> typed readings (doc/protocols.md section 5).

Section 5 holds the frames, markers, accepted DLCs and the decisions on what real devices
send. ``MESSAGES`` states each frame once (reading, DLCs, bits; the dialects' rows come from
sma_dialects), checked against msg_defs/sma.dbc by the first codec, with the rules a DBC
cannot say (0x351's zero limit, 0x35A's online pair); SmaCodec runs the whole family.
"""
from __future__ import annotations

import enum
import functools
from dataclasses import astuple, dataclass, field, fields, replace
from typing import Any, Callable, Union

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import check_dlc, Frame, load_dbc
from ams_can_bridge.protocols.layout import BadValue, Layout
from ams_can_bridge.protocols.sma_dialects import (
    ascii_message, ascii_text, DIALECT_IDS, DIALECTS, DialectReading, DLC_1_TO_8, encode_ascii,
    Message, pad_unsent, PYLONTECH_EXTREMES, PYLONTECH_IDS, PylontechCellExtremes,
    PylontechCellIds, sma_field, VICTRON_BMS_NAME1_ID)

LIMITS_ID = 0x351
SOC_ID = 0x355
BATTERY_ID = 0x356
ALARMS_ID = 0x35A
MANUFACTURER_ID = 0x35E
INFO_ID = 0x35F
SMA_IDS = frozenset({LIMITS_ID, SOC_ID, BATTERY_ID, ALARMS_ID, MANUFACTURER_ID, INFO_ID})
# %: the high-resolution SoC counts only within this of the integer SoC (section 5).
HIRES_AGREEMENT_PCT = 1.0
# %/bit of 0x355 bytes 4-5, tried in this order: SMA's 0.01 %, and the 0.1 % an Orion BMS 2
# sends (its own DBC: HvBatterySOChighdef 0.1 %; 835 at SoC 83 %). The integer SoC decides.
HIRES_SCALES = (0.01, 0.1)
# 0x35A byte 7 bits 2-3: Victron's system status (2 = online, 1 = offline), not a warning.
ONLINE_CODES = (None, False, True, None)  # pair value -> online
# 0x355 as BMS families send it: 'sma' SoC, SoH, high-resolution SoC (6 bytes); 'byd' SoC,
# SoH and zeros (8 bytes, BYD LVS); 'diybms' the SoC alone (DLC 2).
SOC_LAYOUTS = ('sma', 'byd', 'diybms')


class SmaFlag(enum.IntEnum):
    """State of one alarm / warning condition (wire value 3 also means NOT_SUPPORTED)."""

    NOT_SUPPORTED = 0
    ACTIVE = 1
    OK = 2


_FLAGS = (SmaFlag.NOT_SUPPORTED, SmaFlag.ACTIVE, SmaFlag.OK, SmaFlag.NOT_SUPPORTED)

# 0x35A's conditions in wire order (alarms from byte 0, warnings from byte 4).
SMA_CONDITIONS = (
    'general', 'high_voltage', 'low_voltage', 'high_temperature',
    'low_temperature', 'high_temperature_charge', 'low_temperature_charge',
    'high_discharge_current',
    'high_charge_current', 'contactor', 'short_circuit', 'bms_internal',
    'cell_imbalance', 'reserved1', 'reserved2', 'generator',
)
# The warning whose pair (byte 7 bits 2-3) Victron-style BMSs use for the online status.
ONLINE_CONDITION = 'reserved1'


@dataclass(frozen=True)
class SmaLimits:
    """0x351: charge / discharge limits (None = not available)."""

    charge_voltage_v: float | None
    charge_current_a: float | None
    discharge_current_a: float | None
    discharge_voltage_v: float | None


@dataclass(frozen=True)
class SmaSoc:
    """
    0x355: SoC and SoH in %, the optional high-resolution SoC.

    ``soc_hires_pct`` is bytes 4-5 read at SMA's 0.01 %/bit (as decoded and encoded); the
    scale the sender meant is decided against the integer SoC (``hires_scale``).
    """

    soc_pct: int | None
    soh_pct: int | None
    soc_hires_pct: float | None = None

    @property
    def hires_raw(self) -> int | None:
        """Return bytes 4-5 as sent (None: not sent or the 0xFFFF marker)."""
        return None if self.soc_hires_pct is None else round(self.soc_hires_pct * 100)

    @property
    def hires_scale(self) -> float | None:
        """
        Return the %/bit at which bytes 4-5 agree with the integer SoC (None: at none).

        835 with SoC 83 is 83.5 % at 0.1 %/bit (8.35 % at 0.01 disagrees); zeros with SoC 67
        agree at neither. Where both agree (a SoC below about 1 %) SMA's 0.01 is taken.
        """
        raw = self.hires_raw
        if raw is None or self.soc_pct is None:
            return None
        for scale in HIRES_SCALES:
            if abs(raw / round(1 / scale) - self.soc_pct) <= HIRES_AGREEMENT_PCT:
                return scale
        return None

    @property
    def hires_used(self) -> bool:
        """Tell whether the high-resolution SoC agrees with the integer one (and is used)."""
        return self.hires_scale is not None

    @property
    def hires_percent(self) -> float | None:
        """Return the high-resolution SoC (%) at the agreeing scale, None where none agrees."""
        scale = self.hires_scale
        raw = self.hires_raw
        return None if scale is None or raw is None else raw / round(1 / scale)

    @property
    def percent(self) -> float | None:
        """Return the SoC (%) to publish: the high-resolution one where it agrees, else integer."""
        hires = self.hires_percent
        if hires is not None:
            return hires
        return None if self.soc_pct is None else float(self.soc_pct)


@dataclass(frozen=True)
class SmaBattery:
    """0x356: voltage, current (positive = charging, the ROS sign), temperature."""

    voltage_v: float | None
    current_a: float | None
    temperature_c: float | None


@dataclass(frozen=True)
class SmaAlarms:
    """
    0x35A: every condition's alarm and warning flag, keyed by SMA_CONDITIONS names.

    ``online``: Victron's system status in byte 7 bits 2-3 (True online, False offline, None
    not sent); that pair is never the 'reserved1' warning.
    """

    alarms: dict[str, SmaFlag] = field(default_factory=dict)  # completed by __post_init__
    warnings: dict[str, SmaFlag] = field(default_factory=dict)
    online: bool | None = None

    def __post_init__(self) -> None:
        # Conditions left out are NOT_SUPPORTED, so a partial dict equals its decoded frame.
        for kind in ('alarms', 'warnings'):
            given = getattr(self, kind)
            unknown = set(given) - set(SMA_CONDITIONS)
            if unknown:
                raise EncodeRangeError(f'sma.{kind}', sorted(unknown),
                                       'condition names ' + ', '.join(SMA_CONDITIONS))
            object.__setattr__(self, kind, {
                n: given.get(n, SmaFlag.NOT_SUPPORTED) for n in SMA_CONDITIONS})

    @property
    def active_alarms(self) -> tuple[str, ...]:
        """Names of the active alarms, in protocol order."""
        return tuple(n for n in SMA_CONDITIONS if self.alarms.get(n) == SmaFlag.ACTIVE)

    @property
    def active_warnings(self) -> tuple[str, ...]:
        """Names of the active warnings, in protocol order."""
        return tuple(n for n in SMA_CONDITIONS if self.warnings.get(n) == SmaFlag.ACTIVE)


@dataclass(frozen=True)
class SmaManufacturer:
    """0x35E: manufacturer name."""

    name: str


@dataclass(frozen=True)
class SmaBatteryInfo:
    """0x35F: battery type and BMS version (vendor codes), capacity in Ah."""

    battery_type: int | None
    bms_version: int | None
    capacity_ah: int | None


SmaReading = Union[SmaLimits, SmaSoc, SmaBattery, SmaAlarms, SmaManufacturer, SmaBatteryInfo,
                   DialectReading]


ABSOLUTE_ZERO_C = -273.15
# degC: no battery reads hotter: 0x356 at 1,047.6 degC is garbage.
MAX_BATTERY_TEMPERATURE_C = 200.0
_TEMPERATURE_CHECK = ('temperature {value:g} degC is outside {low:g}..{high:g} degC (below '
                      'absolute zero, or hotter than any battery)')
_LIMIT_CHECK = '{value:g} A is negative (a current limit is a magnitude)'


# --- the SMA frames, one row per ID; the dialects' rows are in sma_dialects ------------------
# divide: 1234 -> 12.34. A row's check is a value no BMS may send: the frame is malformed
# (doc/protocols.md section 5.2).
def _limits(data: bytes) -> SmaLimits:
    limits = _D_LIMITS(data)
    if limits.discharge_voltage_v == 0:  # no limit sent, not 0 V
        return replace(limits, discharge_voltage_v=None)
    return limits


def _info(data: bytes) -> SmaBatteryInfo:
    info = _D_INFO(data)
    if info.capacity_ah == 0:  # not sent: SMA's TI has unused fields invalid, 0 is no pack
        return replace(info, capacity_ah=None)
    return info


def _alarms(data: bytes) -> SmaAlarms:
    pairs = _D_ALARMS(data)  # flags; padded with 0xFF: the pairs not sent are NOT_SUPPORTED
    # Built complete here, so skip __post_init__'s normalising (hot path).
    alarms = object.__new__(SmaAlarms)
    object.__setattr__(alarms, 'alarms', dict(zip(SMA_CONDITIONS, pairs)))
    warnings = dict(zip(SMA_CONDITIONS, pairs[16:]))
    warnings[ONLINE_CONDITION] = SmaFlag.NOT_SUPPORTED  # that pair is the online status
    object.__setattr__(alarms, 'warnings', warnings)
    object.__setattr__(alarms, 'online', pairs[_ONLINE])
    return alarms


def _encode_flags(message: SmaAlarms) -> Frame:
    if message.warnings.get(ONLINE_CONDITION, SmaFlag.NOT_SUPPORTED) != 0:
        raise EncodeRangeError(f'sma.warnings.{ONLINE_CONDITION}',
                               message.warnings[ONLINE_CONDITION],
                               'NOT_SUPPORTED (byte 7 bits 2-3 carry SmaAlarms.online)')
    pairs = []
    for kind, flags in (('alarms', message.alarms), ('warnings', message.warnings)):
        for name in SMA_CONDITIONS:
            flag = flags.get(name, SmaFlag.NOT_SUPPORTED)
            if flag not in (0, 1, 2):
                raise EncodeRangeError(f'sma.{kind}.{name}', flag,
                                       'SmaFlag NOT_SUPPORTED, ACTIVE or OK')
            pairs.append(int(flag))
    if message.online is not None:  # byte 7 bits 2-3
        pairs[_ONLINE] = ONLINE_CODES.index(message.online)
    return Frame(ALARMS_ID, _E_ALARMS(*pairs))


MESSAGES = {
    LIMITS_ID: Message(SmaLimits, (6, 7, 8), Layout('SMA_Limits', 8, (
        sma_field('ChargeVoltageLimit', 0, scale=0.1, unit='V', field='charge_voltage_v'),
        sma_field('ChargeCurrentLimit', 16, scale=0.1, signed=True, unit='A',
                  field='charge_current_a', low=0, check='charge current limit ' + _LIMIT_CHECK),
        sma_field('DischargeCurrentLimit', 32, scale=0.1, signed=True, unit='A',
                  field='discharge_current_a', low=0,
                  check='discharge current limit ' + _LIMIT_CHECK),
        sma_field('DischargeVoltageLimit', 48, scale=0.1, unit='V', field='discharge_voltage_v')),
        divide=True), decode=_limits),
    # encoded always 6 bytes (0xFFFF = no high-resolution SoC, as the DBC); SmaCodec.encode_soc
    SOC_ID: Message(SmaSoc, (2, 4, 5, 6, 7, 8), Layout('SMA_SoC', 6, (
        sma_field('SoC', 0, unit='%', field='soc_pct', high=100,
                  check='SoC {value} % is above {high:g} %'),
        sma_field('SoH', 16, unit='%', field='soh_pct', high=100),
        sma_field('SoCHighRes', 32, scale=0.01, unit='%', field='soc_hires_pct', high=100,
                  check='high-resolution SoC {value:g} % is above {high:g} %')),
        divide=True)),
    BATTERY_ID: Message(SmaBattery, (6, 7, 8), Layout('SMA_Battery', 6, (
        # 0.01 V as SMA's TI has it; SmaDevice reads the 0.1 V senders' (sma_scale.py)
        sma_field('Voltage', 0, scale=0.01, signed=True, unit='V', field='voltage_v', low=0,
                  check='pack voltage {value:g} V (at 0.01 V/bit) is negative'),
        sma_field('Current', 16, scale=0.1, signed=True, unit='A', field='current_a'),
        sma_field('Temperature', 32, scale=0.1, signed=True, unit='degC', field='temperature_c',
                  low=ABSOLUTE_ZERO_C, high=MAX_BATTERY_TEMPERATURE_C,
                  check=_TEMPERATURE_CHECK)), divide=True)),
    ALARMS_ID: Message(SmaAlarms, DLC_1_TO_8, Layout('SMA_AlarmsWarnings', 8, tuple(
        sma_field('SystemOnline', first + 2 * k, 2, lookup=ONLINE_CODES)
        if (kind, name) == ('Warning', ONLINE_CONDITION) else
        sma_field(f'{kind}_{name.title().replace("_", "")}', first + 2 * k, 2, lookup=_FLAGS)
        for kind, first in (('Alarm', 0), ('Warning', 32))
        for k, name in enumerate(SMA_CONDITIONS))), decode=_alarms, encode=_encode_flags),
    MANUFACTURER_ID: ascii_message('sma.manufacturer', SmaManufacturer, 'SMA_Manufacturer'),
    INFO_ID: Message(SmaBatteryInfo, (6, 7, 8), Layout('SMA_BatteryInfo', 6, (
        sma_field('BatteryType', 0, field='battery_type'),
        sma_field('BmsVersion', 16, field='bms_version'),
        sma_field('Capacity', 32, unit='Ah', field='capacity_ah'))), decode=_info),
    **DIALECTS,
}
_ONLINE = 16 + SMA_CONDITIONS.index(ONLINE_CONDITION)  # SystemOnline among the pairs
_D_LIMITS: Callable[[bytes], SmaLimits] = MESSAGES[LIMITS_ID].layout.decoder(into=SmaLimits)
_D_INFO: Callable[[bytes], SmaBatteryInfo] = MESSAGES[INFO_ID].layout.decoder(into=SmaBatteryInfo)
_D_ALARMS = MESSAGES[ALARMS_ID].layout.decoder()
_E_ALARMS = MESSAGES[ALARMS_ID].layout.encoder()


@functools.cache
def check_dbc() -> None:
    """Raise LayoutError unless msg_defs/sma.dbc has the bits of every row of MESSAGES."""
    db = load_dbc('sma')
    for frame_id, message in MESSAGES.items():
        message.layout.check_dbc(db.get_message_by_frame_id(frame_id), 'msg_defs/sma.dbc', 'SMA')


# --- what SmaCodec runs, built from the rows ---------------------------------------------------
def _decoder(m: Message) -> Callable[[bytes], SmaReading]:
    if m.decode is not None:
        return m.decode
    if m.text:
        reading, lead = m.reading, m.lead
        return lambda data: reading(*lead, ascii_text(data))
    return m.layout.decoder(into=m.reading)


def _encoder(frame_id: int, m: Message) -> Callable[[Any], Frame]:
    if m.encode is not None:
        return m.encode
    if m.text:
        return _encode_text
    encode = m.layout.encoder(exact=False)  # telemetry: rounded to the step
    return lambda message: Frame(frame_id, encode(*astuple(message)))


# (reading, its values before the text) -> (ID, field name)
_TEXT_IDS = {(m.reading, *m.lead): (frame_id, m.text)
             for frame_id, m in MESSAGES.items() if m.text}


def _encode_text(message: SmaReading) -> Frame:
    *lead, text = astuple(message)
    found = _TEXT_IDS.get((type(message), *lead))
    if found is None:  # a BMS name part or cell id kind no frame carries
        known = [(key[1], field) for key, (_, field) in _TEXT_IDS.items()
                 if key[0] is type(message)]
        raise EncodeRangeError(f'{known[0][1]}.{fields(message)[0].name}', lead[0],
                               'one of ' + ', '.join(str(value) for value, _ in known))
    frame_id, field = found
    return Frame(frame_id, encode_ascii(field, text))


# ID -> (accepted DLCs, length a shorter frame is padded to (0: never), its layout, decoder,
# what a wrong DLC means)
_DECODERS = {frame_id: (m.dlcs, m.layout.length if m.pad and not m.text else 0, m.layout,
                        _decoder(m), m.dlc_note) for frame_id, m in MESSAGES.items()}
_ENCODERS = {m.reading: _encoder(frame_id, m) for frame_id, m in MESSAGES.items()}
# The binary 0x370 / 0x371 of Pylontech V2 (the simulator, tests): rows of sma_dialects
for _reading, _frame_id, _layout in (
        (PylontechCellExtremes, VICTRON_BMS_NAME1_ID, PYLONTECH_EXTREMES),
        (PylontechCellIds, VICTRON_BMS_NAME1_ID + 1, PYLONTECH_IDS)):
    _ENCODERS[_reading] = _encoder(_frame_id, Message(_reading, (8,), _layout))


class SmaCodec:
    """Decode and encode the SMA BMS frames 0x351..0x35F and the dialects' 0x359..0x382."""

    is_extended_id = False
    arbitration_ids = SMA_IDS | DIALECT_IDS

    def __init__(self) -> None:
        """Decode with the tables compiled at import (checked against sma.dbc in the tests)."""

    def decode(self, arbitration_id: int, data: bytes) -> SmaReading:
        """Decode one frame; MalformedFrameError for an unknown ID, a DLC or value out of range."""
        entry = _DECODERS.get(arbitration_id)
        if entry is None:
            raise MalformedFrameError(arbitration_id, data, 'not an SMA BMS ID')
        dlcs, length, layout, decode, dlc_note = entry
        if len(data) not in dlcs:
            try:
                check_dlc(arbitration_id, data, dlcs)
            except MalformedFrameError as exc:
                if not dlc_note:
                    raise
                raise MalformedFrameError(arbitration_id, data,
                                          f'{exc.reason}: {dlc_note}') from None
        if len(data) < length:
            data = pad_unsent(data, layout)
        try:
            return decode(data)
        except BadValue as exc:
            raise MalformedFrameError(arbitration_id, data, str(exc)) from None

    def encode_soc(self, message: SmaSoc, layout: str = 'sma') -> Frame:
        """0x355 laid out as a BMS family sends it (SOC_LAYOUTS; the simulator's variants)."""
        if layout == 'sma':
            return self.encode(message)
        if layout not in SOC_LAYOUTS:
            raise EncodeRangeError('sma.soc_layout', layout, 'one of ' + ', '.join(SOC_LAYOUTS))
        data = self.encode(SmaSoc(message.soc_pct, message.soh_pct, None)).data
        return Frame(SOC_ID, data[:2] if layout == 'diybms' else data[:4] + bytes(4))

    def encode(self, message: SmaReading) -> Frame:
        """Encode any SMA message (None fields as invalid markers); EncodeRangeError else."""
        encode = _ENCODERS.get(type(message))
        if encode is None:
            raise EncodeRangeError('message', message, 'an SMA, Pylontech or Victron message')
        return encode(message)
