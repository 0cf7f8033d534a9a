# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA EVMS3 and its BMS12 cell modules: 29-bit frames <-> typed readings and commands.

doc/protocols.md section 3 holds the frames, codes, sources and decisions. This codec owns
every ID on the bus: the BMS12 frames (``protocols.bms12``), the TC chargers
(``protocols.tc_charger``) and the configuration (``protocols.evms3_config``, re-exported
here). The bits are ``LAYOUTS``, checked with the others against msg_defs/evms3.dbc.
"""
from __future__ import annotations

import enum
import functools
from dataclasses import astuple, dataclass, replace
from typing import Any, Callable, Sequence

from ams_can_bridge.errors import ConfigError, EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import check_dlc, Frame, load_dbc, TEMP_C_MAX
from ams_can_bridge.protocols.evms3_config import (  # noqa: F401 (some re-exported)
    BMS12_MAX_MODULES, BmsCellNumbers, cell_numbers_payload, check_config_value, CONFIG_FIELDS,
    CONFIG_FILLER, CONFIG_LAYOUTS, config_payloads, ConfigReadback, ConfigReport,
    CORE_REQUEST_CONFIG, CORE_SEND_CELL_NUMS, decode_cell_numbers,
    decode_config_packet, decode_report, Evms3Settings, Evms3ConfigPart, OtherTraffic,
    READBACK_IDS, READBACK_NAMES)
from ams_can_bridge.protocols import bms12
from ams_can_bridge.protocols.bms12 import (
    BMS12_BASE_ID, Bms12Cells, Bms12Request, Bms12Temperatures, decode_cells)
from ams_can_bridge.protocols.layout import BadValue, check_value, Layout, LITTLE, Signal
from ams_can_bridge.protocols.tc_charger import (
    CHARGER_IDS, ChargerCommand, ChargerStatus, LAYOUTS as TC_LAYOUTS, TcChargerCodec)

BMS16_MARKER = 255  # ID 30 byte 5 (aux voltage on an EVMS3): EVMS_Monitor3.c sets isBMS16
CORE_SETUP_EDIT_TEMP_GAUGE = 3  # ID 31 byte 0, the last of Common.h's setup states
STATUS, SET_STATE, CONFIG1, CONFIG2, CONFIG3, CONFIG4 = range(6)
CELL_NUMBERS, ACK_ERROR, RESET_SOC, POWER_OFF, BATTERY_CURRENT, ZERO_CURRENT = range(6, 12)


class Evms3State(enum.IntEnum):
    """Status byte bits 2..0."""

    IDLE = 0
    PRECHARGING = 1
    RUNNING = 2
    CHARGING = 3
    STOPPED = 4
    SETUP = 5


class Evms3Error(enum.IntEnum):
    """Status byte bits 7..3 (vendor names)."""

    NONE = 0
    CORRUPT_SETTINGS = 1
    OVERCURRENT_WARNING = 2
    OVERCURRENT_SHUTDOWN = 3
    LOW_CELL_WARNING = 4
    BMS_SHUTDOWN = 5  # undervoltage cell for 10+ s
    HIGH_CELL_WARNING = 6
    BMS_ENDED_CHARGE = 7  # overvoltage cell for > 1 s
    BMS_OVER_TEMP = 8
    BMS_UNDER_TEMP = 9
    LOW_SOC_WARNING = 10
    OVERTEMPERATURE = 11  # the EVMS core's own sensor
    ISOLATION_ERROR = 12
    LOW_12V = 13
    PRECHARGE_FAILED = 14
    CONTACTOR_SWITCH_ERROR = 15
    BMS_COMMS_ERROR = 16  # a BMS12 module stopped answering


EVMS3_WARNINGS = frozenset({2, 4, 6, 10})
_ERROR_CODE = Signal('ErrorCode', 3, 5, LITTLE, field='error', lookup=tuple(Evms3Error),
                     check='unknown error code {value} ({low}..{high})')


# --- the wire layout: one table, checked against msg_defs/evms3.dbc --------------------------
# ZEVA's firmware divides (1234 -> 123.4 V): divide=True keeps those values exact. The rows
# are in the order of their reading's fields: one generated call each way.
LAYOUTS = {
    'EVMS3_Status': Layout('EVMS3_Status', 8, (
        Signal('State', 0, 3, LITTLE, field='state', lookup=tuple(Evms3State),
               check='unknown state {value} ({low}..{high})'),
        _ERROR_CODE,
        Signal('AmpHoursRemaining', 15, 16, scale=0.1, unit='Ah', field='amp_hours_ah'),
        Signal('BatteryVoltage', 31, 16, scale=0.1, unit='V', field='pack_voltage_v'),
        Signal('AuxVoltage', 40, 8, LITTLE, scale=0.1, unit='V', field='aux_voltage_v'),
        Signal('Headlights', 55, 1, LITTLE, field='headlights', flag=True),
        Signal('IsolationIntegrity', 48, 7, LITTLE, high=100, unit='%', field='isolation_pct',
               invalid=101, check='isolation {value} % (0..100, 101 = n/a)'),  # 101: n/a
        Signal('Temperature', 56, 8, LITTLE, offset=-40, high=TEMP_C_MAX, unit='degC',
               field='temperature_c', invalid=0,  # raw 0: no sensor
               check='temperature {value} degC (allowed {low:g}..{high:g})')),
        divide=True),
    'EVMS3_AcknowledgeError': Layout('EVMS3_AcknowledgeError', 1, (
        replace(_ERROR_CODE, start=0, length=8),)),  # the same codes, a whole byte
    'EVMS3_BatteryCurrent': Layout('EVMS3_BatteryCurrent', 3, (
        Signal('BatteryCurrent', 7, 24, scale=0.001, offset=-8388.608, unit='A',
               field='current_a'),), divide=True),
    **{name: Layout(name, 0, ()) for name in (  # the commands without data (DLC 0)
        'EVMS3_ResetSoc', 'EVMS3_PowerOff', 'EVMS3_ZeroCurrentSensor')},
}
_ENCODERS = {name: layout.encoder() for name, layout in LAYOUTS.items()}


@functools.cache
def check_dbc() -> None:
    """Raise LayoutError unless msg_defs/evms3.dbc has the bits of LAYOUTS."""
    db = load_dbc('evms3')
    # the configuration is sent on 32..36 and read back on 52..56 in the same layout
    readback = [f'EVMS3_SendConfig{k}' for k in range(1, 5)] + ['EVMS3_SendCellNumbers']
    for name, layout in [*LAYOUTS.items(), *bms12.LAYOUTS.items(), *zip(readback, CONFIG_LAYOUTS),
                         *((layout.name, layout) for layout in CONFIG_LAYOUTS)]:
        layout.check_dbc(db.get_message_by_name(name), 'msg_defs/evms3.dbc', 'EVMS3')
    for n in range(1, 4):  # the TC chargers 1..3 the EVMS drives: one layout each way
        for kind in ('Command', 'Status'):
            TC_LAYOUTS[f'TC_Charger1_{kind}'].check_dbc(
                db.get_message_by_name(f'TC_Charger{n}_{kind}'), 'msg_defs/evms3.dbc',
                'TC charger')


# --- readings and commands ------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Evms3Status:
    """ID 30: the EVMS broadcast (4 Hz)."""

    state: Evms3State
    error: Evms3Error
    amp_hours_ah: float  # remaining
    pack_voltage_v: float
    aux_voltage_v: float
    headlights: bool
    isolation_pct: int | None  # None: could not be measured (raw 101)
    temperature_c: int | None  # None: no sensor (raw 0)

    @property
    def bms16_marker(self) -> bool:
        """Tell whether byte 5 is 255: a BMS16 in its standard form, not an EVMS3."""
        return round(self.aux_voltage_v * 10) == BMS16_MARKER


@dataclass(frozen=True, slots=True)
class SetState:
    """
    ID 31: enter Setup (True) or return to Idle (False).

    DLC 2: a Monitor editing a gauge setting (section 3.2), ``request`` 1..3 and the
    ``gauge_value`` shown meanwhile; the EVMS3 stays in Setup.
    """

    setup: bool
    request: int | None = None  # DLC 2 only: CORE_SETUP_STATE 1, EDIT_FUEL 2, EDIT_TEMP 3
    gauge_value: int | None = None


@dataclass(frozen=True, slots=True)
class AcknowledgeError:
    """ID 37: acknowledge this error code."""

    error: Evms3Error


@dataclass(frozen=True, slots=True)
class ResetSoc:
    """ID 38: reset the state of charge to 100 % (sent with DLC 0: 100 % for every firmware)."""


@dataclass(frozen=True, slots=True)
class RequestConfig:
    """ID 51 (DLC 0): ask the EVMS for its whole configuration; it answers on 52..56."""


@dataclass(frozen=True, slots=True)
class PowerOff:
    """ID 39: power the EVMS off."""


@dataclass(frozen=True, slots=True)
class BatteryCurrent:
    """ID 40: battery current from the current sensor, A, positive = discharge."""

    current_a: float


@dataclass(frozen=True, slots=True)
class ZeroCurrentSensor:
    """ID 41: zero the current sensor."""


# The readings one layout states, by offset from base_id: one generated call each way
_GENERATED = {STATUS: (Evms3Status, 'EVMS3_Status'),
              ACK_ERROR: (AcknowledgeError, 'EVMS3_AcknowledgeError'),
              RESET_SOC: (ResetSoc, 'EVMS3_ResetSoc'), POWER_OFF: (PowerOff, 'EVMS3_PowerOff'),
              BATTERY_CURRENT: (BatteryCurrent, 'EVMS3_BatteryCurrent'),
              ZERO_CURRENT: (ZeroCurrentSensor, 'EVMS3_ZeroCurrentSensor')}
_LAYOUT_OF = {cls: (offset, name) for offset, (cls, name) in _GENERATED.items()}


def generated(layout: Layout, into: Callable, *names: str) -> Callable[[int, bytes], Any]:
    """Return decode(aid, data) of a reading one layout states: its DLC, values and checks."""
    decode, length = layout.decoder(*names, into=into), layout.length

    def run(aid: int, data: bytes) -> Any:
        if len(data) != length:
            check_dlc(aid, data, length)
        try:  # the reading built in one generated call; its rows refuse an unknown code
            return decode(data)
        except BadValue as exc:
            raise MalformedFrameError(aid, data, str(exc)) from None
    return run


def payload(msg: Any) -> tuple[int, bytes]:
    """Return (offset, data) of a reading of _GENERATED, each value checked by its row."""
    offset, name = _LAYOUT_OF[type(msg)]
    return offset, _ENCODERS[name](*astuple(msg))


# --- the codec -------------------------------------------------------------------------------
class Evms3Codec:
    """EVMS3 frames at base_id + 0..11, BMS12 modules 0..bms12_modules-1, TC chargers 1..3."""

    def __init__(self, base_id: int = 30, bms12_modules: int = BMS12_MAX_MODULES,
                 bms12_base: int = BMS12_BASE_ID, extended_id: bool = True,
                 voltage_multiplier: int = 1) -> None:
        """Decode/encode at base_id (+ the fixed read-back IDs 51..56); ValueError on overlap."""
        if voltage_multiplier not in (1, 2):
            raise ConfigError(f'voltage_multiplier {voltage_multiplier!r}: allowed 1 or 2')
        self.voltage_multiplier = voltage_multiplier
        # ZEVA's firmware uses 29-bit IDs unless built with USE_29BIT_IDS 0; the TC chargers
        # on the same bus always use 29-bit IDs, so one EVMS3 may need both widths.
        top = 0x1FFFFFFF if extended_id else 0x7FF
        if not 0 <= base_id <= top - 11:
            raise ConfigError(f'base_id {base_id} outside 0..0x{top - 11:X} '
                              f'({29 if extended_id else 11}-bit IDs)')
        if not 0 <= bms12_modules <= BMS12_MAX_MODULES:
            raise ConfigError(f'bms12_modules {bms12_modules} outside 0..16')
        self.is_extended_id = bool(extended_id)
        self.base_id = base_id
        self.bms12_base = bms12_base
        self.bms12_modules = bms12_modules
        self._bms12 = {bms12_base + 10 * m + t: (m, t)
                       for m in range(bms12_modules) for t in range(5)}
        own = set(range(base_id, base_id + 12))
        if own & set(self._bms12):
            raise ConfigError(f'EVMS3 IDs {base_id}..{base_id + 11} overlap the BMS12 IDs '
                              f'{bms12_base}..{bms12_base + 10 * bms12_modules - 6}')
        fixed = set(range(CORE_REQUEST_CONFIG, CORE_SEND_CELL_NUMS + 1))
        if fixed & (own | set(self._bms12)):
            raise ConfigError(f'EVMS3 IDs {base_id}..{base_id + 11} or the BMS12 IDs overlap '
                              'the read-back IDs 51..56 (fixed in the EVMS3 firmware)')
        own |= set(READBACK_IDS)  # 51 is not listened to: on a ZEVA bus it may be throttle
        self.chargers = TcChargerCodec()
        self.arbitration_ids = frozenset(own | set(self._bms12) | CHARGER_IDS)
        # (ID, 29-bit) pairs: the node dispatches on both, so an 11-bit EVMS3 still gets its
        # chargers' 29-bit frames and no 29-bit frame with an EVMS3 number reaches it.
        self.frame_ids = frozenset({(i, self.is_extended_id) for i in own | set(self._bms12)}
                                   | {(i, True) for i in CHARGER_IDS})
        b = base_id
        self._decoders = {b + offset: generated(LAYOUTS[name], cls)
                          for offset, (cls, name) in _GENERATED.items()}
        self._decoders.update({
            b + SET_STATE: self._decode_set_state,
            b + CELL_NUMBERS: lambda aid, data: BmsCellNumbers(decode_cell_numbers(aid, data)),
            # any DLC: ZEVA's 2021 firmware reads a SoC byte, older firmware none
            b + RESET_SOC: lambda aid, data: ResetSoc(),
        })
        for packet in range(4):
            self._decoders[b + CONFIG1 + packet] = functools.partial(
                decode_config_packet, packet, multiplier=voltage_multiplier)
        for aid in READBACK_IDS:  # 52..56: the EVMS's answer to 51 (or foreign traffic)
            self._decoders[aid] = functools.partial(decode_report, multiplier=voltage_multiplier)

    # --- decode ---------------------------------------------------------------------------
    def decode(self, arbitration_id: int, data: bytes) -> Any:
        """Frame -> reading; MalformedFrameError for a wrong DLC, impossible value or ID."""
        decoder = self._decoders.get(arbitration_id)
        if decoder is not None:
            return decoder(arbitration_id, data)
        module_type = self._bms12.get(arbitration_id)
        if module_type is None:
            if arbitration_id in CHARGER_IDS:
                return self.chargers.decode(arbitration_id, data)
            raise MalformedFrameError(arbitration_id, data, 'not an EVMS3/BMS12 ID of this codec')
        module, t = module_type
        if 1 <= t <= 3 and len(data) == 8:  # the bulk of the bus: cells in one call
            try:
                return decode_cells(data, module, 4 * (t - 1))
            except BadValue:  # worded with the module by bms12.decode
                pass
        return bms12.decode(arbitration_id, data, module, t)

    def _decode_set_state(self, aid: int, data: bytes) -> SetState:
        check_dlc(aid, data, (1, 2))
        if len(data) == 2:  # the Monitor's TransmitGaugeState
            if not 1 <= data[0] <= CORE_SETUP_EDIT_TEMP_GAUGE:
                raise MalformedFrameError(aid, data, f'set state {data[0]} with a gauge value, '
                                          'expected 1..3')
            return SetState(True, data[0], data[1])
        if data[0] > 1:
            raise MalformedFrameError(aid, data, f'set state {data[0]}, expected 0 or 1')
        return SetState(bool(data[0]))

    # --- encode ---------------------------------------------------------------------------
    def _frame(self, offset: int, data: bytes | bytearray) -> Frame:
        return Frame(self.base_id + offset, bytes(data), self.is_extended_id)

    def config_frames(self, cfg: Evms3Settings) -> list[Frame]:
        """Build the frames of IDs 32, 33, 34, 35 in that order (EncodeRangeError first)."""
        return [self._frame(CONFIG1 + i, p)
                for i, p in enumerate(config_payloads(cfg, self.voltage_multiplier))]

    def report_frames(self, cfg: Evms3Settings, cells_per_module: Sequence[int]) -> list[Frame]:
        """Build the EVMS's answer to ID 51: the frames of 32..36 at the fixed IDs 52..56."""
        frames = self.config_frames(cfg) + [self.encode(BmsCellNumbers(tuple(cells_per_module)))]
        return [frame._replace(arbitration_id=aid) for aid, frame in zip(READBACK_IDS, frames)]

    def encode(self, msg: Any) -> Frame:
        """Reading/command -> Frame; EncodeRangeError names the field and allowed range."""
        if type(msg) in _LAYOUT_OF:
            return self._frame(*payload(msg))
        if isinstance(msg, SetState):
            if msg.request is not None:  # the Monitor's gauge edit (DLC 2)
                return self._frame(SET_STATE, bytes([
                    check_value('request', msg.request, 1, CORE_SETUP_EDIT_TEMP_GAUGE,
                                integer=True),
                    check_value('gauge_value', msg.gauge_value or 0, 0, 255, integer=True)]))
            return self._frame(SET_STATE, bytes([1 if msg.setup else 0]))
        if isinstance(msg, Evms3ConfigPart):
            cfg = Evms3Settings.from_mapping({**CONFIG_FILLER, **msg.values})
            return self.config_frames(cfg)[msg.part - 1]
        if isinstance(msg, BmsCellNumbers):
            return self._frame(CELL_NUMBERS, cell_numbers_payload(msg.cells_per_module))
        if isinstance(msg, RequestConfig):  # DLC 0 too, at a fixed ID
            return Frame(CORE_REQUEST_CONFIG, b'', self.is_extended_id)
        if isinstance(msg, (Bms12Request, Bms12Cells, Bms12Temperatures)):
            return bms12.encode(msg, self.bms12_base, self.is_extended_id)
        if isinstance(msg, (ChargerCommand, ChargerStatus)):
            return self.chargers.encode(msg)
        raise EncodeRangeError('message', msg, 'an EVMS3, BMS12 or TC charger message')
