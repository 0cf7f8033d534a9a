# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A dbc device never publishes what no battery reports (issue 35, points 3 and 6).

Real material: the Nissan Leaf battery's ``LB_SOC`` (unit ``%+1``, 0.1 % per bit:
test/fixtures/nissan_leaf), cantools' own float-signal DBC (range ``[0|0]``:
test/fixtures/cantools), and the Orion BMS 2 profile on an Orion whose messages were
customised in its utility (frames typed from the profile's layout).
"""
from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.errors import ConfigError
from helpers import Clock

FIXTURES = Path(__file__).resolve().parent / 'fixtures'
LEAF = FIXTURES / 'nissan_leaf' / 'leaf_battery.dbc'
FLOATS = FIXTURES / 'cantools' / 'floating_point.dbc'
# LB_SOC 805 (80.5 %): 10 bits Motorola from bit 7: 805 = 0b1100100101 -> C9 40
LEAF_55B = bytes.fromhex('C940AA0000000000')
# 0x1DB: LB_Current 0, LB_Total_Voltage raw 720 = 360 V (bits 23..14: 0xB4 0x00)
LEAF_1DB = bytes.fromhex('0000B40000000000')
# The Orion capture's 0x6B0 (test_probe_profiles): 282.4 V, SoC 80.5 %, checksum CF
ORION_6B0 = bytes.fromhex('00000B08A10162CF')


def leaf_device(tmp_path: Path, soc: str) -> DbcDevice:
    mapping = tmp_path / 'leaf.yaml'
    mapping.write_text('primary: x1DB\nbattery_state:\n  voltage: x1DB.LB_Total_Voltage\n'
                       f'  current: x1DB.LB_Current\n  percentage: {soc}\n', encoding='utf-8')
    return DbcDevice('leaf', {'dbc_file': str(LEAF), 'mapping_file': str(mapping)}, Clock())


# --- 35.3: a percentage outside 0..1 ---------------------------------------------------------
def test_leaf_soc_in_an_unknown_unit_is_refused_at_start_saying_which_unit_to_give(tmp_path):
    with pytest.raises(ConfigError) as info:
        leaf_device(tmp_path, 'x55B.LB_SOC')
    text = str(info.value)
    assert "battery_state.percentage: x55B.LB_SOC has unit '%+1'" in text
    assert 'its DBC range 0..1000 is not 0..1: give its unit with unit:' in text
    assert "'‰' (0.1 % per bit) reads that range as 0..100 %" in text


def test_leaf_soc_with_its_unit_given_reads_80_5_percent(tmp_path):
    device = leaf_device(tmp_path, '{signal: x55B.LB_SOC, unit: "0.1 %"}')
    device.handle_frame(0x55B, LEAF_55B, 1.0)
    device.handle_frame(0x1DB, LEAF_1DB, 1.0)
    report = device.battery_report()
    assert report.percentage == pytest.approx(0.805)
    assert report.voltage == pytest.approx(360.0)
    assert device.frames_malformed == 0


def test_leaf_soc_given_in_the_wrong_unit_is_never_published_and_named(tmp_path):
    # '%': 805 % -> 8.05, no ratio: NaN, counted, the WARN names the signal and its value
    device = leaf_device(tmp_path, '{signal: x55B.LB_SOC, unit: "%"}')
    device.handle_frame(0x55B, LEAF_55B, 1.0)
    device.handle_frame(0x1DB, LEAF_1DB, 1.0)
    assert math.isnan(device.battery_report().percentage)
    assert device.frames_malformed == 1
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'implausible: x55B.LB_SOC = 805 %+1 (implausible for percentage 0..1)' \
        in diag.message


def test_spellings_of_tenths_of_a_percent_read_the_same(tmp_path):
    for unit in ('‰', '0.1%', 'permille'):
        device = leaf_device(tmp_path, f'{{signal: x55B.LB_SOC, unit: "{unit}"}}')
        device.handle_frame(0x55B, LEAF_55B, 1.0)
        device.handle_frame(0x1DB, LEAF_1DB, 1.0)
        assert device.battery_report().percentage == pytest.approx(0.805), unit


# --- 35.6: plausibility ------------------------------------------------------------------------
def float_device(tmp_path: Path) -> DbcDevice:
    mapping = tmp_path / 'floats.yaml'
    mapping.write_text('primary: Message1\nbattery_state:\n'
                       '  voltage: {signal: Message1.Signal1, unit: V}\n'
                       '  current: {signal: Message2.Signal1, unit: A}\n'
                       '  temperature: {signal: Message2.Signal2, unit: degC}\n',
                       encoding='utf-8')
    return DbcDevice('floats', {'dbc_file': str(FLOATS), 'mapping_file': str(mapping)},
                     Clock())


def test_cantools_float_signals_never_publish_inf_or_1e30(tmp_path):
    device = float_device(tmp_path)
    device.handle_frame(0x401, struct.pack('<ff', 12.5, 25.0), 1.0)
    device.handle_frame(0x400, struct.pack('<d', 48.0), 1.0)
    report = device.battery_report()
    assert (report.voltage, report.current, report.temperature) == (48.0, 12.5, 25.0)
    assert device.frames_malformed == 0
    device.handle_frame(0x400, struct.pack('<d', math.inf), 1.0)
    assert math.isnan(device.battery_report().voltage)
    assert device.frames_malformed == 1
    assert 'Message1.Signal1 = inf' in device.diagnostic_report().message
    device.handle_frame(0x400, struct.pack('<d', 1e30), 1.0)
    device.handle_frame(0x401, struct.pack('<ff', math.nan, -300.0), 1.0)
    report = device.battery_report()
    assert math.isnan(report.voltage) and math.isnan(report.current)
    assert math.isnan(report.temperature)
    assert device.frames_malformed == 3
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'Message1.Signal1 = 1e+30 (implausible for voltage 0..1500 V)' in diag.message
    assert 'Message2.Signal2 = -300 (implausible for temperature -90..200 degC)' in diag.message
    assert 'Message2.Signal1 = nan' in diag.message


def test_a_customised_orion_read_with_the_profile_is_named_not_published():
    # 0x6B1 customised in the Orion utility: byte 4 (High_Temperature) 0x9E = -98 degC
    clock = Clock(1.0)
    device = DbcDevice('orion', {'profile': 'orion_bms2'}, clock)
    custom = bytes.fromhex('001200049E1100')
    custom += bytes([(0x6B1 + 8 + sum(custom)) & 0xFF])
    device.handle_frame(0x6B1, custom, 1.0)
    device.handle_frame(0x6B0, ORION_6B0, 1.0)
    report = device.battery_report()
    assert math.isnan(report.temperature) and report.voltage == pytest.approx(282.4)
    assert device.frames_malformed == 1
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert ('MSGID_0X6B1.High_Temperature = -98 Celsius (implausible for temperature '
            '-90..200 degC)') in diag.message
    assert "the BMS may not send profile orion_bms2's layout" in diag.message
