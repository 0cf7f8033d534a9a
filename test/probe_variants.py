# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The device variants the simulator plays, for probe's round trips (test_probe_*.py).

Each variant: the simulators (built fresh), the bridge parameters that describe them as
the simulator was configured (the *truth*: what a team would write knowing the devices),
what probe must write, and the cells each device has. The tests run the simulator's
frames through ``probe --output`` and then through the engine with exactly that file.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from ams_can_bridge.protocols.ivt_s import IvtMux
from ams_can_bridge.sim.ams import AmsSimulator
from ams_can_bridge.sim.base import SimDevice
from ams_can_bridge.sim.bms16 import Bms16Simulator
from ams_can_bridge.sim.bms16_std import Bms16StdSimulator
from ams_can_bridge.sim.evms3 import Evms3Simulator
from ams_can_bridge.sim.ivt_s import IvtSSimulator
from ams_can_bridge.sim.main import build_devices
from ams_can_bridge.sim.sma import SmaSimulator

ZEROS = [0] * 16
SMA_CELLS = 16  # the SMA simulator's pack
LFP_EMPTY_V, LFP_FULL_V = 2.5, 3.65  # V a LiFePO4 cell reads empty and full


@dataclass
class Variant:
    """One bus the simulator can play, and what probe must make of it."""

    name: str
    build: Callable[[], list[SimDevice]]
    truth: dict[str, Any]                  # flat bridge parameters, devices included
    expect: dict[str, Any]                 # '<instance>.<key>': what probe must decide
    cells: dict[str, int] = field(default_factory=dict)  # instance -> cell_voltage length
    bitrate: int = 500_000
    volts: dict[str, tuple[float, float]] = field(default_factory=dict)  # instance -> V range


def ams_ivt(banks: int, base: int = 0x300, ivt_base: int = 0x521, order: str = 'big',
            cycles: dict | None = None, pad: bool = False) -> Callable[[], list[SimDevice]]:
    """Build an AMS with an IVT-S measuring its pack (as the simulator pairs them)."""
    def build() -> list[SimDevice]:
        ams = AmsSimulator('ams', base_id=base, bank_count=banks, pad=pad)
        ivt = IvtSSimulator('ivt_s', base_id=ivt_base, byte_order=order,
                            current_fn=ams.pack_current_a, voltage_fn=ams.pack_voltage_v,
                            cycles_ms=cycles)
        return [ams, ivt]
    return build


def _ams(banks: int) -> Variant:
    return Variant(f'ams_{banks}_banks', ams_ivt(banks),
                   {'devices': ['ams', 'ivt_s'], 'ams.bank_count': banks},
                   {'ams.base_id': 0x300, 'ams.bank_count': banks, 'ivt_s.base_id': 0x521,
                    'ivt_s.byte_order': 'big', 'ams.pack_voltage_channel': 'U1',
                    'ams.current_sensor': 'ivt_s'},
                   {'ams': 28 * banks})


def _sma(dialect: str, scale: float) -> Variant:
    """SMA in a dialect, 0x356 in 0.01 V or 0.1 V: probe decides the scale from 0x351."""
    soc_layout = {'sma': 'sma', 'pylontech': 'diybms', 'victron': 'byd'}[dialect]
    name = 'sma' if dialect == 'sma' else f'sma_{dialect}'
    return Variant(
        name + ('_tenth_volt' if scale == 0.1 else ''),
        lambda: [SmaSimulator('sma', dialect=dialect, soc_layout=soc_layout,
                              voltage_scale=scale)],
        {'devices': ['sma'], 'sma.voltage_scale': scale}, {},
        volts={'sma': (SMA_CELLS * LFP_EMPTY_V, SMA_CELLS * LFP_FULL_V)})


OFF = {IvtMux.U2: 0, IvtMux.U3: 0, IvtMux.W: 0, IvtMux.WH: 0, IvtMux.I: 20, IvtMux.T: 500}
EVMS3_CELLS = [12, 12, 8, 8, 10, 4]

VARIANTS = [
    *(_ams(banks) for banks in range(1, 6)),
    Variant('ams_padded_no_ivt',
            lambda: [AmsSimulator('ams', base_id=0x200, bank_count=2, pad=True)],
            {'devices': ['ams'], 'ams.base_id': 0x200, 'ams.bank_count': 2},
            {'ams.base_id': 0x200, 'ams.bank_count': 2}, {'ams': 56}),
    Variant('ivt_little', lambda: [IvtSSimulator('ivt_s', byte_order='little')],
            {'devices': ['ivt_s'], 'ivt_s.byte_order': 'little'},
            {'ivt_s.base_id': 0x521, 'ivt_s.byte_order': 'little'}),
    Variant('ivt_big_shifted', lambda: [IvtSSimulator('ivt_s', base_id=0x3C0)],
            {'devices': ['ivt_s'], 'ivt_s.base_id': 0x3C0},
            {'ivt_s.base_id': 0x3C0, 'ivt_s.byte_order': 'big'}),
    Variant('ams_3_ivt_little_shifted_results_off',
            ams_ivt(3, ivt_base=0x400, order='little', cycles=OFF),
            {'devices': ['ams', 'ivt_s'], 'ams.bank_count': 3, 'ivt_s.base_id': 0x400,
             'ivt_s.byte_order': 'little'},
            {'ams.bank_count': 3, 'ivt_s.base_id': 0x400, 'ivt_s.byte_order': 'little',
             'ams.pack_voltage_channel': 'U1'}, {'ams': 84}),
    Variant('evms3_0_modules', lambda: [Evms3Simulator('evms3', bms12_modules=0, chargers=0)],
            {'devices': ['evms3'], 'evms3.bms12_modules': 0},
            {'evms3.base_id': 30, 'evms3.extended_id': True, 'evms3.bms12_modules': 0},
            bitrate=250_000),
    Variant('evms3_6_modules', lambda: [Evms3Simulator(
                'evms3', bms12_modules=6, cells_per_module=EVMS3_CELLS, chargers=0)],
            {'devices': ['evms3'], 'evms3.bms12_modules': 6,
             'evms3.config.cells_per_module': EVMS3_CELLS + ZEROS[6:]},
            {'evms3.bms12_modules': 6,
             'evms3.config.cells_per_module': EVMS3_CELLS + ZEROS[6:]},
            {'evms3': sum(EVMS3_CELLS)}, bitrate=250_000),
    Variant('evms3_16_modules_charging', lambda: [Evms3Simulator(
                'evms3', bms12_modules=16, chargers=2, charge_after_s=1.0)],
            {'devices': ['evms3'], 'evms3.bms12_modules': 16},
            {'evms3.bms12_modules': 16}, {'evms3': 192}, bitrate=250_000),
    Variant('bms16_inverter', lambda: [Bms16Simulator('bms16', cells=14, send_sma=True)],
            {'devices': ['bms16'], 'bms16.config.cells': 14},
            {'bms16.base_id': 500, 'bms16.config.cells': 14}, {'bms16': 14}),
    Variant('bms16_standard', lambda: [Bms16StdSimulator('bms16', cells=12)],
            {'devices': ['bms16'], 'bms16.variant': 'standard', 'bms16.config.cells': 12},
            {'bms16.variant': 'standard', 'bms16.base_id': 30, 'bms16.config.cells': 12},
            {'bms16': 12}, bitrate=250_000),
    *(_sma(dialect, scale) for dialect in ('sma', 'pylontech', 'victron')
      for scale in (0.01, 0.1)),
]

# The shipped dbc profiles as `simulator --profile NAME` plays them (sim/dbc.py): foxBMS 2's
# default pack (18 cells, 8 sensors) and the Orion BMS 2's standard messages (no cells)
PROFILE_VARIANTS = [
    Variant(f'profile_{profile}', lambda profile=profile: build_devices(['dbc'], profile=profile),
            {'devices': [name], f'{name}.type': 'dbc', f'{name}.profile': profile}, {}, cells)
    for profile, name, cells in (('foxbms2', 'foxbms2', {'foxbms2': 18}),
                                 ('orion_bms2', 'orion', {}))]
BY_NAME = {v.name: v for v in VARIANTS + PROFILE_VARIANTS}
