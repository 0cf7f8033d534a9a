# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The device types this package ships, one :class:`DeviceType` each.

``setup.py`` registers each under the entry-point group ``ams_can_bridge.devices`` (as any
other package registers its own); ``registry.py`` also reads this tuple directly, so that a
source checkout run without installed metadata still knows its own types. Importing this
module imports no device code: every class is a lazy 'module:Name' string.
"""
from __future__ import annotations

from ams_can_bridge.devices.descriptor import DeviceType, Variant

AMS = DeviceType(
    name='ams', rank=0,
    device='ams_can_bridge.devices.ams.device:AmsDevice',
    protocol='ams_can_bridge.protocols.ams',
    # the AMS goes first so the IVT-S can measure its pack (simulator)
    simulator='ams_can_bridge.sim.ams:AmsSimulator',
    recognisers=('ams_can_bridge.probe.ams:recognise',),
    simulated_by_default=True)

IVT_S = DeviceType(
    name='ivt_s', rank=1,
    device='ams_can_bridge.devices.ivt_s.device:IvtSDevice',
    protocol='ams_can_bridge.protocols.ivt_s',
    simulator='ams_can_bridge.sim.ivt_s:IvtSSimulator',
    recognisers=('ams_can_bridge.probe.ivt_s:recognise',),
    simulated_by_default=True)

EVMS3 = DeviceType(
    name='evms3', rank=2,
    device='ams_can_bridge.devices.evms3.device:Evms3Device',
    protocol='ams_can_bridge.protocols.evms3',
    simulator='ams_can_bridge.sim.evms3:Evms3Simulator',
    recognisers=('ams_can_bridge.probe.evms3:recognise',),
    simulated_by_default=True)

# BMS16: 'inverter' = the 11-bit / 500 kbit/s units "intended for CAN integration with
# inverters" (doc/protocols.md section 4), 'standard' = the EVMS3 protocol (section 6).
BMS16 = DeviceType(
    name='bms16', rank=3,
    device='ams_can_bridge.devices.bms16.inverter:Bms16Device',
    protocol='ams_can_bridge.protocols.bms16',
    simulator='ams_can_bridge.sim.bms16:Bms16Simulator',
    recognisers=('ams_can_bridge.probe.bms16:recognise',),
    simulated_by_default=True,
    variants=(
        Variant('inverter', 'ams_can_bridge.devices.bms16.inverter:Bms16Device',
                'ams_can_bridge.sim.bms16:Bms16Simulator'),
        Variant('standard', 'ams_can_bridge.devices.bms16.standard:Bms16StdDevice',
                'ams_can_bridge.sim.bms16_std:Bms16StdSimulator'),
    ),
    variant_help=('wire form of the BMS16: inverter (11-bit, 500 kbit/s, IDs 500.. and the SMA '
                  'frames; doc/protocols.md section 4) or standard (BMS16v2 standard form: '
                  'EVMS3 protocol, 29-bit, 250 kbit/s; section 6), which has its own base_id '
                  'default and config.* parameters'))

SMA = DeviceType(
    name='sma', rank=4,
    device='ams_can_bridge.devices.sma.device:SmaDevice',
    protocol='ams_can_bridge.protocols.sma',
    simulator='ams_can_bridge.sim.sma:SmaSimulator',
    # sma_voltage refines the sma candidate: the 0x356 voltage scale from the limits
    recognisers=('ams_can_bridge.probe.sma:recognise',
                 'ams_can_bridge.probe.sma_voltage:recognise'),
    simulated_by_default=True)

# dbc: a team's own BMS from its DBC (--dbc/--mapping), not in the simulator's default set;
# probe recognises the shipped profiles (they leave a device of the bridge its IDs).
DBC = DeviceType(
    name='dbc', rank=5,
    device='ams_can_bridge.devices.dbc.device:DbcDevice',
    protocol='ams_can_bridge.protocols.dbc_codec',
    simulator='ams_can_bridge.sim.dbc:DbcSimulator',
    recognisers=('ams_can_bridge.probe.profiles:recognise',))

# pack: several members' reports combined; nothing on the bus of its own.
PACK = DeviceType(
    name='pack', rank=6,
    device='ams_can_bridge.devices.pack.device:PackDevice',
    protocol='')  # no wire format: it reads its members' reports

BUILT_IN = (AMS, IVT_S, EVMS3, BMS16, SMA, DBC, PACK)
