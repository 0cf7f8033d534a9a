"""A BMS DBC and mapping written by hand for the dbc device tests (foxBMS-2-like names)."""
from __future__ import annotations

from pathlib import Path

# Little-endian except BMS_PackValues (Motorola, as many BMSs send). Cell voltages and
# temperatures are multiplexed: 2 per frame, mux 0 and 1. Units as real DBCs write them.
OUR_BMS_DBC = '''VERSION ""

NS_ :
	CM_
	VAL_

BS_:

BU_: BMS

BO_ 544 BMS_State: 2 BMS
 SG_ mode : 0|4@1+ (1,0) [0|3] "" Vector__XXX
 SG_ error : 8|8@1+ (1,0) [0|255] "" Vector__XXX

BO_ 546 BMS_PackValues: 8 BMS
 SG_ batteryVoltage : 7|16@0+ (10,0) [0|600000] "mV" Vector__XXX
 SG_ packCurrent : 23|24@0- (1,0) [-1000000|1000000] "mA" Vector__XXX

BO_ 561 BMS_MinMax: 4 BMS
 SG_ maximumCellTemp : 0|8@1- (1,0) [-40|125] "degC" Vector__XXX
 SG_ minimumCellVoltage : 8|16@1+ (1,0) [0|5000] "mV" Vector__XXX

BO_ 565 BMS_StateEstimation: 2 BMS
 SG_ packSoc : 0|10@1+ (0.1,0) [0|100] "%" Vector__XXX

BO_ 576 BMS_CellVoltages: 8 BMS
 SG_ mux M : 0|8@1+ (1,0) [0|1] "" Vector__XXX
 SG_ cellVoltage_000 m0 : 8|16@1+ (1,0) [0|5000] "mV" Vector__XXX
 SG_ cellVoltage_001 m0 : 24|16@1+ (1,0) [0|5000] "mV" Vector__XXX
 SG_ cellVoltage_000_invalidFlag m0 : 56|1@1+ (1,0) [0|1] "" Vector__XXX
 SG_ cellVoltage_001_invalidFlag m0 : 57|1@1+ (1,0) [0|1] "" Vector__XXX
 SG_ cellVoltage_002 m1 : 8|16@1+ (1,0) [0|5000] "mV" Vector__XXX
 SG_ cellVoltage_003 m1 : 24|16@1+ (1,0) [0|5000] "mV" Vector__XXX
 SG_ cellVoltage_002_invalidFlag m1 : 56|1@1+ (1,0) [0|1] "" Vector__XXX
 SG_ cellVoltage_003_invalidFlag m1 : 57|1@1+ (1,0) [0|1] "" Vector__XXX

BO_ 592 BMS_CellTemperatures: 3 BMS
 SG_ mux M : 0|8@1+ (1,0) [0|1] "" Vector__XXX
 SG_ cellTemperature_000 m0 : 8|8@1- (1,0) [-40|125] "degC" Vector__XXX
 SG_ cellTemperature_001 m0 : 16|8@1- (1,0) [-40|125] "degC" Vector__XXX
 SG_ cellTemperature_002 m1 : 8|8@1- (1,0) [-40|125] "degC" Vector__XXX
 SG_ cellTemperature_003 m1 : 16|8@1- (1,0) [-40|125] "degC" Vector__XXX

VAL_ 544 mode 0 "STANDBY" 1 "CHARGE" 2 "DRIVE" 3 "ERROR" ;
'''

OUR_MAPPING = '''primary: BMS_PackValues
battery_state:
  voltage: BMS_PackValues.batteryVoltage
  current: {signal: BMS_PackValues.packCurrent, scale: -1}
  percentage: BMS_StateEstimation.packSoc
  temperature: BMS_MinMax.maximumCellTemp
  cell_voltage:
    signal: "BMS_CellVoltages.cellVoltage_{i:03d}"
    count: 4
    invalid: "BMS_CellVoltages.cellVoltage_{i:03d}_invalidFlag"
  cell_temperature: {signal: "BMS_CellTemperatures.cellTemperature_{i:03d}", count: 4}
  power_supply_status: {signal: BMS_State.mode, map: {CHARGE: CHARGING, DRIVE: DISCHARGING}}
  power_supply_health: {signal: BMS_State.error, map: {0: GOOD}, otherwise: UNSPEC_FAILURE}
  design_capacity: 20.0
diagnostics:
  values: all
  levels:
    - {signal: BMS_State.error, not_equal: 0, level: ERROR, message: "BMS error {value}"}
    - {signal: BMS_MinMax.minimumCellVoltage, below: 3000, level: WARN}
'''

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
