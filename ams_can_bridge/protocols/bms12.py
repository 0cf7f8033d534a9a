# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA BMS12 cell modules on an EVMS3 bus: frames <-> typed readings (doc/protocols.md 3.3).

The bits are one table (``LAYOUTS``) that ``evms3.check_dbc`` proves against
msg_defs/evms3.dbc. The EVMS3 codec owns the IDs (``300 + 10 m + t``) and calls ``decode`` /
``encode`` here; a BMS16 in its standard form sends its cells in these frames too.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import CELL_V_MAX, check_dlc, Frame, TEMP_C_MAX
from ams_can_bridge.protocols.layout import BadValue, BIG, check_value, Layout, LITTLE, Signal

BMS12_BASE_ID = 300
BMS12_MAX_MODULES = 16


@dataclass(frozen=True, slots=True)
class Bms12Request:
    """BMS12 t=0 (EVMS -> module): balance (shunt) voltage in mV, None = no balancing."""

    module: int
    balance_mv: int | None


@dataclass(frozen=True, slots=True)
class Bms12Cells:
    """BMS12 t=1..3: four cell voltages (V) starting at cell index first_cell (0, 4, 8)."""

    module: int
    first_cell: int
    voltages_v: tuple[float, float, float, float]


@dataclass(frozen=True, slots=True)
class Bms12Temperatures:
    """BMS12 t=4: the module's two temperatures (degC; None = no sensor, raw 0)."""

    module: int
    temperatures_c: tuple[int | None, int | None]


def _cells(first: int) -> tuple[Signal, ...]:
    # uint16 mV carries up to 65.535 V: above CELL_V_MAX it is no cell (section "Physical
    # bounds"), and the frame is malformed
    return tuple(Signal(f'Cell{first + k}', 7 + 16 * k, 16, BIG, scale=0.001, high=CELL_V_MAX,
                        unit='V', field=f'voltages_v[{k}]',
                        check='cell voltage {value:g} V (allowed {low:g}..{high:g} V)')
                 for k in range(4))


# ZEVA's firmware divides (3456 -> 3.456 V): divide=True keeps those values exact.
LAYOUTS = {
    'BMS12_M0_Request': Layout('BMS12_M0_Request', 2, (
        Signal('BalanceVoltage', 7, 16, BIG, scale=0.001, unit='V'),), divide=True),
    'BMS12_M0_Cells1to4': Layout('BMS12_M0_Cells1to4', 8, _cells(1), divide=True),
    'BMS12_M0_Cells5to8': Layout('BMS12_M0_Cells5to8', 8, _cells(5), divide=True),
    'BMS12_M0_Cells9to12': Layout('BMS12_M0_Cells9to12', 8, _cells(9), divide=True),
    # Raw 0 = no sensor (section 3.3)
    'BMS12_M0_Temperatures': Layout('BMS12_M0_Temperatures', 8, tuple(
        Signal(f'Temperature{k + 1}', 8 * k, 8, LITTLE, offset=-40, high=TEMP_C_MAX,
               unit='degC', field=f'temperatures_c[{k}]', invalid=0,
               check='temperature {value} degC (allowed {low:g}..{high:g} degC)')
        for k in range(2)), divide=True),
}
_D_REQUEST = LAYOUTS['BMS12_M0_Request'].decoder(raw=True)  # the firmware's mV
_E_CELLS = LAYOUTS['BMS12_M0_Cells1to4'].encoder()
_D_TEMPS = LAYOUTS['BMS12_M0_Temperatures'].decoder()
_E_TEMPS = LAYOUTS['BMS12_M0_Temperatures'].encoder()
# The bulk of an EVMS3 bus: a cell frame in one generated call (module, first cell, values);
# the same bits for the three frames
decode_cells = LAYOUTS['BMS12_M0_Cells1to4'].decoder(into=Bms12Cells, pack=2)


def decode(aid: int, data: bytes, module: int, t: int) -> Any:
    """Frame t of module -> reading; MalformedFrameError for a wrong DLC or value."""
    if t == 0:
        check_dlc(aid, data, 2)
        mv, = _D_REQUEST(data)
        return Bms12Request(module, mv or None)
    try:
        if t == 4:
            # The BMS12 PDF says DLC 2; ZEVA's firmware sends 8 (section 3.3)
            check_dlc(aid, data, (2, 8))
            return Bms12Temperatures(module, _D_TEMPS(data))
        if len(data) != 8:
            check_dlc(aid, data, 8)
        return decode_cells(data, module, 4 * (t - 1))
    except BadValue as exc:  # a cell or temperature no battery has
        raise MalformedFrameError(aid, data, f'module {module}: {exc}') from None


def encode(msg: Bms12Request | Bms12Cells | Bms12Temperatures, base_id: int,
           extended_id: bool) -> Frame:
    """Build the frame of a module reading (IDs from base_id); EncodeRangeError if bad."""
    module = check_value('module', msg.module, 0, BMS12_MAX_MODULES - 1, integer=True)
    base = base_id + 10 * module
    if isinstance(msg, Bms12Request):
        mv = 0 if msg.balance_mv is None else check_value(
            'balance_mv', msg.balance_mv, 1, 65535, integer=True)
        return Frame(base, mv.to_bytes(2, 'big'), extended_id)
    if isinstance(msg, Bms12Temperatures):
        if len(msg.temperatures_c) != 2:
            raise EncodeRangeError('temperatures_c', msg.temperatures_c, '2 values')
        return Frame(base + 4, _E_TEMPS(*msg.temperatures_c), extended_id)
    if msg.first_cell not in (0, 4, 8):
        raise EncodeRangeError('first_cell', msg.first_cell, '0, 4 or 8')
    if len(msg.voltages_v) != 4:
        raise EncodeRangeError('voltages_v', msg.voltages_v, '4 values')
    return Frame(base + 1 + msg.first_cell // 4, _E_CELLS(*msg.voltages_v), extended_id)
