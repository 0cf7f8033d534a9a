# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A dbc device's timeouts follow the traffic; missing groups are named early (issue 35.5, 35.7).

A real Orion BMS 2 sends 0x6B0/0x6B1 once a second when its utility says so, while the
profile's DBC says 8 ms / 104 ms (frames typed from the WE-EV capture,
test/fixtures/orion_bms2). A Formula Student HV DBC's 108 cells come positioned by
cellboard and group; one cellboard never sends (a DBC of that shape typed here: 6 boards
x 6 groups x 3 cells).
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.errors import ConfigError
from helpers import Clock

ORION_6B1 = bytes.fromhex('00120004141100F4')  # 20 degC, the capture's frame
ORION_6B0 = bytes.fromhex('00000B08A10162CF')  # 282.4 V, SoC 80.5 %


def orion_second(device: DbcDevice, clock: Clock) -> None:
    device.handle_frame(0x6B1, ORION_6B1, clock.now)
    device.handle_frame(0x6B0, ORION_6B0, clock.now)


def test_an_orion_sending_once_a_second_keeps_its_temperature():
    clock = Clock(10.0)
    device = DbcDevice('orion', {'profile': 'orion_bms2', 'stale_timeout': 5.0}, clock)
    assert device.group_timeout(1) == pytest.approx(0.52)  # 5 x the DBC's 104 ms
    orion_second(device, clock)
    clock.now += 1.0
    orion_second(device, clock)  # one period heard: 3 x 1 s from now on
    assert device.group_timeout(1) == pytest.approx(3.0)
    for _ in range(5):
        for _ in range(9):
            clock.now += 0.1
            assert device.battery_report().temperature == 20.0
            assert 'expired' not in device.diagnostic_report().message
        clock.now += 0.1
        orion_second(device, clock)
    assert device.learned_periods()['MSGID_0X6B1'] == pytest.approx(1.0)
    # silent: unknown after 3 periods, not kept for ever
    clock.now += 3.1
    assert math.isnan(device.battery_report().temperature)
    assert 'messages expired' in device.diagnostic_report().values


def test_a_pause_is_not_learned_as_a_rate():
    clock = Clock(0.0)
    device = DbcDevice('orion', {'profile': 'orion_bms2', 'stale_timeout': 5.0}, clock)
    for _ in range(5):
        orion_second(device, clock)
        clock.now += 1.0
    clock.now += 30.0  # the bus was lost for 30 s
    orion_second(device, clock)
    assert device.group_timeout(1) == pytest.approx(3.0)
    clock.now += 3.1
    assert math.isnan(device.battery_report().temperature)


def test_the_timeouts_parameter_gives_the_rate_from_the_start():
    clock = Clock(0.0)
    device = DbcDevice('orion', {'profile': 'orion_bms2', 'stale_timeout': 5.0,
                                 'timeouts': ['MSGID_0X6B1=3']}, clock)
    orion_second(device, clock)
    clock.now += 0.9  # the first second: no period heard yet
    assert device.battery_report().temperature == 20.0
    with pytest.raises(ConfigError) as info:
        DbcDevice('orion', {'profile': 'orion_bms2', 'timeouts': ['MSGID_6B1=3', 'MSGID_0X6B0']},
                  clock)
    assert "'MSGID_6B1' is not a message the mapping reads; closest: MSGID_0X6B1" \
        in str(info.value)
    assert "'MSGID_0X6B0': write 'Message=seconds'" in str(info.value)


# --- 35.7: a cellboard that never sends -------------------------------------------------------
FS_DBC = '''VERSION ""

NS_ :
\tBA_DEF_
\tBA_

BS_:

BU_: AMS

BO_ 1024 AMS_Status: 2 AMS
 SG_ AMS_State : 0|8@1+ (1,0) [0|15] "" Vector__XXX

BO_ 1040 Cell_Voltages: 8 AMS
 SG_ Cellboard : 0|4@1+ (1,0) [0|5] "" Vector__XXX
 SG_ Group : 4|4@1+ (1,0) [0|5] "" Vector__XXX
 SG_ Cell_0 : 16|16@1+ (0.0001,0) [0|6.5535] "V" Vector__XXX
 SG_ Cell_1 : 32|16@1+ (0.0001,0) [0|6.5535] "V" Vector__XXX
 SG_ Cell_2 : 48|16@1+ (0.0001,0) [0|6.5535] "V" Vector__XXX

BA_DEF_ BO_ "GenMsgCycleTime" INT 0 10000;
BA_ "GenMsgCycleTime" BO_ 1024 100;
BA_ "GenMsgCycleTime" BO_ 1040 50;
'''
FS_MAPPING = '''primary: AMS_Status
battery_state:
  cell_voltage:
    signal: "Cell_Voltages.Cell_{i}"
    per_frame: 3
    position: {Cellboard: {stride: 18}, Group: {stride: 3}}
    count: 108
'''


def cells_frame(board: int, group: int) -> bytes:
    return bytes([board | group << 4, 0]) + (37000).to_bytes(2, 'little') * 3


def test_a_silent_cellboard_is_named_once_the_others_came_twice(tmp_path: Path):
    (tmp_path / 'fs.dbc').write_text(FS_DBC, encoding='utf-8')
    (tmp_path / 'fs.yaml').write_text(FS_MAPPING, encoding='utf-8')
    clock = Clock(0.0)
    device = DbcDevice('hv', {'dbc_file': str(tmp_path / 'fs.dbc'),
                              'mapping_file': str(tmp_path / 'fs.yaml')}, clock)
    # 5 x 50 ms x 36 positions: the timeout since start alone would wait 9 s
    assert device.group_timeout(1) == pytest.approx(9.0)
    first_warn = None
    for step in range(200):  # boards 0..4 in turn, a frame every 25 ms; board 5 silent
        board, group = divmod(step % 30, 6)
        device.handle_frame(0x410, cells_frame(board, group), clock.now)
        if step % 4 == 0:
            device.handle_frame(0x400, b'\x01\x00', clock.now)
        diag = device.diagnostic_report()
        if diag.level != Level.OK and first_warn is None:
            first_warn = step
            assert '18 of 108 cell voltages unknown: Cell_Voltages element 90..107 ' \
                'not received' in diag.message, diag.message
        clock.now += 0.025
    assert first_warn == 59  # the second frame of the last group heard: 1.5 s after start
    report = device.battery_report()
    assert sum(math.isnan(v) for v in report.cell_voltage) == 18
