# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""A BMS DBC and mapping written by hand for the dbc device tests (fixtures/our_bms.*)."""
from __future__ import annotations

from pathlib import Path

FIXTURES = Path(__file__).resolve().parent / 'fixtures'
# Little-endian except BMS_PackValues (Motorola, as many BMSs send). Cell voltages and
# temperatures are multiplexed: 2 per frame, mux 0 and 1. Units as real DBCs write them.
OUR_BMS_DBC_FILE = FIXTURES / 'our_bms.dbc'
OUR_MAPPING_FILE = FIXTURES / 'our_bms_mapping.yaml'  # the contract's example mapping
OUR_BMS_DBC = OUR_BMS_DBC_FILE.read_text(encoding='utf-8')
OUR_MAPPING = OUR_MAPPING_FILE.read_text(encoding='utf-8')
# The parameters of a dbc instance on these files (their IDs 0x220..0x250 are no built-in
# device's: the every-device tests add it beside the others).
OUR_PARAMS = {'dbc_file': str(OUR_BMS_DBC_FILE), 'mapping_file': str(OUR_MAPPING_FILE)}

# Frames written by hand from the DBC above (bytes worked out bit by bit in the comments).
FRAMES = {
    # batteryVoltage raw 40000 = 0x9C40 (x10 mV = 400 V), Motorola bytes 0-1; packCurrent
    # +50000 mA = 0x00C350 (the BMS counts discharge positive), Motorola bytes 2-4
    'pack': (0x222, bytes.fromhex('9C4000C350000000')),
    'soc': (0x235, bytes.fromhex('6B03')),  # raw 875 = 0x36B, 0.1 % -> 87.5 %
    'minmax': (0x231, bytes.fromhex('23420E00')),  # 35 degC; 0x0E42 = 3650 mV
    'cells0': (0x240, bytes.fromhex('00740E7E0E000000')),  # mux 0: 3700, 3710 mV
    'cells1': (0x240, bytes.fromhex('016A0E880E000002')),  # mux 1: 3690, 3720 mV, 003 invalid
    'temps0': (0x250, bytes.fromhex('00191A')),  # mux 0: 25, 26 degC
    'temps1': (0x250, bytes.fromhex('011BE2')),  # mux 1: 27, -30 degC (0xE2)
    'state': (0x220, bytes.fromhex('0200')),  # mode DRIVE, error 0
}


def write_files(folder: Path, dbc: str = OUR_BMS_DBC,
                mapping: str = OUR_MAPPING) -> dict[str, str]:
    """Write the DBC and mapping into folder; return the device parameters for them."""
    (folder / 'our_bms.dbc').write_text(dbc, encoding='utf-8')
    (folder / 'pack_mapping.yaml').write_text(mapping, encoding='utf-8')
    return {'dbc_file': str(folder / 'our_bms.dbc'),
            'mapping_file': str(folder / 'pack_mapping.yaml'), 'stale_timeout': 1.0}
