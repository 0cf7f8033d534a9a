# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Isabellenhuette IVT-S current shunt: result frames <-> typed readings (doc/protocols.md 2.1).

The command (0x411) and answer (0x511) frames are in protocols/ivt_s_commands.py. The DBC can
describe only the big-endian value; the little-endian variant is the same table with that one
signal changed.
"""
from __future__ import annotations

from dataclasses import astuple, dataclass
import enum
import functools
from typing import Any, Callable

from ams_can_bridge.errors import ConfigError, EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import (
    ABSOLUTE_ZERO_C, check_dlc, Frame, load_dbc, TEMP_C_MAX)
from ams_can_bridge.protocols.layout import compile_function, Layout, LITTLE, Signal

COMMAND_ID = 0x411
RESPONSE_ID = 0x511
DEFAULT_BASE_ID = 0x521
DLC = 6
BYTE_ORDERS = ('big', 'little')
INT32_MIN = -(1 << 31)
INT32_MAX = (1 << 31) - 1
_new = object.__new__


class IvtMux(enum.IntEnum):
    """The result a frame carries (its MuxID byte); result k is sent at base_id + k."""

    I = 0  # noqa: E741 (the vendor's name for the current result)
    U1 = 1
    U2 = 2
    U3 = 3
    T = 4
    W = 5
    AS = 6
    WH = 7


# Vendor unit per raw count, as a divisor to SI (A, V, degC, W, As, Wh): dividing keeps
# decimal raw values exact (1500 mA -> 1.5 A) where multiplying by 0.001 would not.
DIVISOR = {IvtMux.I: 1000, IvtMux.U1: 1000, IvtMux.U2: 1000, IvtMux.U3: 1000,
           IvtMux.T: 10, IvtMux.W: 1, IvtMux.AS: 1, IvtMux.WH: 1}
RAW_UNIT = {IvtMux.I: 'mA', IvtMux.U1: 'mV', IvtMux.U2: 'mV', IvtMux.U3: 'mV',
            IvtMux.T: '0.1 degC', IvtMux.W: 'W', IvtMux.AS: 'As', IvtMux.WH: 'Wh'}
SI_UNIT = {IvtMux.I: 'A', IvtMux.U1: 'V', IvtMux.U2: 'V', IvtMux.U3: 'V',
           IvtMux.T: 'degC', IvtMux.W: 'W', IvtMux.AS: 'As', IvtMux.WH: 'Wh'}
# Name of each result in msg_defs/ivt_s.dbc (IVT_Msg_Result_<name>).
DBC_NAME = {IvtMux.I: 'I', IvtMux.U1: 'U1', IvtMux.U2: 'U2', IvtMux.U3: 'U3',
            IvtMux.T: 'T', IvtMux.W: 'W', IvtMux.AS: 'As', IvtMux.WH: 'Wh'}


@dataclass(frozen=True)
class IvtResult:
    """
    One IVT-S result frame: which result, counter, status bits, raw and SI value.

    raw is in the vendor unit (mA, mV, 0.1 degC, W, As, Wh); value in SI (A, V, degC, W,
    As, Wh), with the sensor's sign (no mounting-direction correction at this layer).
    """

    kind: IvtMux
    counter: int
    ocs: bool
    result_error: bool
    measurement_error: bool
    system_error: bool
    raw: int
    value: float

    @classmethod
    def from_value(cls, kind: IvtMux, value: float, counter: int = 0, ocs: bool = False,
                   result_error: bool = False, measurement_error: bool = False,
                   system_error: bool = False) -> 'IvtResult':
        """Build a result from an SI value (rounded to the vendor unit), e.g. to encode it."""
        kind = IvtMux(kind)
        if value != value or value in (float('inf'), float('-inf')):
            raise EncodeRangeError(f'IVT-S {kind.name} value', value, 'a finite number')
        raw = round(value * DIVISOR[kind])
        return cls(kind, counter, ocs, result_error, measurement_error, system_error,
                   raw, raw / DIVISOR[kind])

    @property
    def status_bits(self) -> int:
        """Byte 1 bits 7..4 as sent (OCS = 0x10 .. system error = 0x80), placed by the table."""
        return _ENCODE_I(0, 0, self.ocs, self.result_error, self.measurement_error,
                         self.system_error, 0)[1]


# Where a physical bound applies (section 2.1): a temperature no sensor on a battery reads.
# Current, voltages (signed by the wiring), power and the counters have none.
_BOUNDS: dict[IvtMux, dict[str, Any]] = {IvtMux.T: dict(
    low=ABSOLUTE_ZERO_C, high=TEMP_C_MAX,
    check='temperature {value:g} degC (allowed {low:g}..{high:g} degC)')}


def _layout(kind: IvtMux) -> Layout:
    name = DBC_NAME[kind]
    result = f'IVT_Result_{name}'
    return Layout(f'IVT_Msg_Result_{name}', DLC, (
        Signal(f'IVT_ID_Result_{name}', 7, 8, field='IVT-S MuxID'),
        Signal(f'IVT_MsgCount_Result_{name}', 11, 4, field='IVT-S counter'),
        Signal(f'{result}_OCS', 12, 1, field='ocs', flag=True),
        Signal(f'{result}_Channel_Error', 13, 1, field='result_error', flag=True),
        Signal(f'{result}_Measurement_Error', 14, 1, field='measurement_error', flag=True),
        Signal(f'{result}_System_Error', 15, 1, field='system_error', flag=True),
        Signal(result, 23, 32, signed=True, scale=1 / DIVISOR[kind] if kind == IvtMux.T else 1,
               unit=SI_UNIT[kind] if kind == IvtMux.T else RAW_UNIT[kind],
               field=f'IVT-S {kind.name} raw value', **_BOUNDS.get(kind, {}))))
    # the DBC scales only T


LAYOUTS = {kind: _layout(kind) for kind in IvtMux}
# The raw values a result may carry: its row's range where it has a check, else any int32.
RAW_LIMITS = {kind: layout.signals[-1].raw_limits() if layout.signals[-1].check
              else (INT32_MIN, INT32_MAX) for kind, layout in LAYOUTS.items()}
# The sensor can be set to send the value little-endian (its byte 2 first).
LITTLE_LAYOUTS = {kind: layout.replace(f'IVT_Result_{DBC_NAME[kind]}', start=16,
                                       byte_order=LITTLE) for kind, layout in LAYOUTS.items()}
# Byte 1 -> the reading's counter and status bits.
_BYTE1_FIELDS = ('counter', 'ocs', 'result_error', 'measurement_error', 'system_error')
_BYTE1 = LAYOUTS[IvtMux.I].decoder(*(s.name for s in LAYOUTS[IvtMux.I].signals[1:6]))
_ENCODE_I = LAYOUTS[IvtMux.I].encoder()


@functools.cache
def check_dbc() -> None:
    """Fail loudly (LayoutError) if msg_defs/ivt_s.dbc no longer has the bits of LAYOUTS."""
    db = load_dbc('ivt_s')
    for kind, layout in LAYOUTS.items():
        layout.check_dbc(db.get_message_by_frame_id(DEFAULT_BASE_ID + kind),
                         'msg_defs/ivt_s.dbc', 'IVT-S')


# The bus thread decodes every frame (8 results x up to 100 Hz): the value's bits are read
# inline, counter and status bits come from tables per byte 1, and a frozen dataclass
# __init__ (object.__setattr__ per field, half the time) is replaced by filling __dict__.
_DECODE_SOURCE = '''def decode(self, arbitration_id, data):
    entry = self._by_id.get(arbitration_id)
    if entry is None or len(data) != {dlc} or data[0] != entry[0]:
        self._reject(arbitration_id, data)
    kind, divisor, fields, low, high = entry
    raw = {raw}
    if not low <= raw <= high:
        self._out_of_range(arbitration_id, data, kind, raw)
    result = new(IvtResult)
    state = result.__dict__
    state.update(fields[data[1]])
    state['raw'] = raw
    state['value'] = raw / divisor
    return result
'''


def _decoder(layout: Layout) -> Any:
    source = _DECODE_SOURCE.format(dlc=DLC, raw=layout.raw_expression(layout.signals[-1]))
    return compile_function(source, layout.name, 'decode', {'new': _new, 'IvtResult': IvtResult})


_DECODERS: dict[str, Callable[[IvtSCodec, int, bytes], IvtResult]] = {
    'big': _decoder(LAYOUTS[IvtMux.I]), 'little': _decoder(LITTLE_LAYOUTS[IvtMux.I])}


class IvtSCodec:
    """
    Decode IVT-S result frames (and encode them, for the simulator).

    base_id: ID of the current result (the others follow); byte_order: 'big' (factory) or
    'little' for the 32-bit value.
    """

    is_extended_id = False

    def __init__(self, base_id: int = DEFAULT_BASE_ID, byte_order: str = 'big') -> None:
        if byte_order not in BYTE_ORDERS:
            raise ConfigError(f'IVT-S byte_order = {byte_order!r}: allowed '
                              + ' | '.join(repr(b) for b in BYTE_ORDERS))
        if not 0 <= base_id <= 0x7FF - 7:
            raise ConfigError(f'IVT-S base_id = {base_id!r} (0x{base_id:X}): allowed '
                              f'0..0x{0x7FF - 7:X} (11-bit IDs, 8 results from base_id)')
        self.base_id = base_id
        self.byte_order = byte_order
        self.arbitration_ids = frozenset(base_id + k for k in IvtMux)
        layouts = LAYOUTS if byte_order == 'big' else LITTLE_LAYOUTS
        # decode, generated with the value's bits inline (the bus thread's hottest call):
        # the instance attribute takes the place of the method above.
        self.decode = _DECODERS[byte_order].__get__(self)  # type: ignore[method-assign]
        self._encoders = {kind: layout.replace(
            f'IVT_Result_{DBC_NAME[kind]}', scale=1, unit=RAW_UNIT[kind],
            low=RAW_LIMITS[kind][0], high=RAW_LIMITS[kind][1]).encoder()
            for kind, layout in layouts.items()}  # the raw value, in the vendor unit
        # ID -> (kind, divisor, fields by byte 1, raw limits): one dict lookup finds
        # everything decode needs.
        self._by_id = {base_id + kind: (kind, DIVISOR[kind], [
            {'kind': kind, **dict(zip(_BYTE1_FIELDS, _BYTE1(bytes((kind, b)))))}
            for b in range(256)], *RAW_LIMITS[kind]) for kind in IvtMux}

    def decode(self, arbitration_id: int, data: bytes) -> IvtResult:
        """Decode one result frame; MalformedFrameError for a wrong ID, DLC or MuxID."""
        return _DECODERS[self.byte_order](self, arbitration_id, data)  # see __init__

    def _reject(self, arbitration_id: int, data: bytes) -> None:
        entry = self._by_id.get(arbitration_id)
        if entry is None:
            raise MalformedFrameError(
                arbitration_id, data,
                f'not an IVT-S result ID (0x{self.base_id:X}..0x{self.base_id + 7:X})')
        check_dlc(arbitration_id, data, DLC)
        kind = entry[0]
        raise MalformedFrameError(
            arbitration_id, data,
            f'MuxID {data[0]} does not match result {kind.name} (MuxID {int(kind)}) '
            f'expected at this ID')

    def _out_of_range(self, arbitration_id: int, data: bytes, kind: IvtMux, raw: int) -> None:
        row = LAYOUTS[kind].signals[-1]
        low, high = row.bounds()
        raise MalformedFrameError(arbitration_id, data, f'{kind.name}: ' + row.check.format(
            value=raw / DIVISOR[kind], low=low, high=high))

    def encode(self, result: IvtResult) -> Frame:
        """Build the frame of one result (the simulator's side of the codec)."""
        kind = IvtMux(result.kind)
        data = self._encoders[kind](*astuple(result)[:-1])  # the layout's order, raw last
        return Frame(self.base_id + kind, data, False)
