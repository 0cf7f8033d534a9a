# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""SmaDevice with the Pylontech and Victron dialects, and every frame group expiring on its own."""
import math

import pytest

from ams_can_bridge.devices.base import Level, PowerSupplyHealth
from ams_can_bridge.devices.sma.device import IDENTITY_TIMEOUT, SmaDevice
from helpers import Clock

# 51.23 V, -12.5 A, 25.3 degC
BATTERY = bytes([0x03, 0x14, 0x83, 0xFF, 0xFD, 0x00])
# 51.23 V, -12.5 A, temperature not available (0x8000)
BATTERY_NO_TEMP = bytes([0x03, 0x14, 0x83, 0xFF, 0x00, 0x80])
# 0x373: min 3300 mV, max 3312 mV, min 288 K, max 300 K (U16 LE)
CELLS = bytes([0xE4, 0x0C, 0xF0, 0x0C, 0x20, 0x01, 0x2C, 0x01])
ALL_OK_35A = bytes([0xAA] * 8)
# 0x351: 55.2 V, 50 A, 100 A, 48 V: the 51.23 V above is in 0.01 V
LIMITS = bytes([0x28, 0x02, 0xF4, 0x01, 0xE8, 0x03, 0xE0, 0x01])


def make():
    clock = Clock(50.0)
    return SmaDevice('sma', {}, clock=clock), clock


def test_pylontech_alarm_is_error_and_sets_health_without_0x35a():
    device, _ = make()
    device.handle_frame(0x356, BATTERY, 1.0)
    device.handle_frame(0x359, bytes([0b0000_0010, 0, 0, 0, 2]), 1.0)  # over-voltage alarm
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert diag.message.startswith('alarms high_voltage')
    assert 'no alarm frame' not in diag.message
    assert diag.values['alarms active (0x359)'] == 'high_voltage'
    assert diag.values['alarm high_voltage (0x359)'] == 'ACTIVE'
    assert diag.values['warning high_voltage (0x359)'] == 'OK'
    assert diag.values['module count'] == '2'
    assert device.battery_report().power_supply_health == PowerSupplyHealth.OVERVOLTAGE


def test_pylontech_warning_is_warn_and_health_stays_good():
    device, _ = make()
    device.handle_frame(0x356, BATTERY, 1.0)
    device.handle_frame(0x359, bytes([0, 0, 0b0001_0000, 0b0000_1000, 1]), 1.0)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'warnings low_temperature, bms_internal' in diag.message
    assert diag.values['warnings active (0x359)'] == 'low_temperature, bms_internal'
    assert device.battery_report().power_supply_health == PowerSupplyHealth.GOOD


def test_pylontech_all_clear_is_ok():
    device, _ = make()
    device.handle_frame(0x356, BATTERY, 1.0)
    device.handle_frame(0x359, bytes(5), 1.0)
    diag = device.diagnostic_report()
    assert diag.level == Level.OK and diag.message.startswith('OK')
    assert device.battery_report().power_supply_health == PowerSupplyHealth.GOOD


def test_0x35a_and_0x359_alarms_add_up():
    device, _ = make()
    device.handle_frame(0x356, BATTERY, 1.0)
    # 0x35A: condition 9 (contactor) = pair at bits 3..2 of byte 2 ACTIVE, the rest OK
    device.handle_frame(0x35A, bytes([0xAA, 0xAA, 0xA6, 0xAA] + [0xAA] * 4), 1.0)
    device.handle_frame(0x359, bytes([0b0000_1000, 0, 0, 0, 1]), 1.0)  # over-temperature
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert diag.message.startswith('alarms contactor, high_temperature')
    assert device.battery_report().power_supply_health == PowerSupplyHealth.OVERHEAT


def test_pylontech_request_flags_are_values_only():
    device, _ = make()
    device.handle_frame(0x356, BATTERY, 1.0)
    device.handle_frame(0x359, bytes(5), 1.0)
    device.handle_frame(0x35C, bytes([0b1010_0000, 0]), 1.0)
    diag = device.diagnostic_report()
    assert diag.values['charge enable'] == 'yes'
    assert diag.values['discharge enable'] == 'no'
    assert diag.values['request charge immediately'] == 'yes'
    assert diag.level == Level.OK


def test_victron_values_in_volts_and_degc():
    device, _ = make()
    device.handle_frame(0x356, BATTERY, 1.0)
    device.handle_frame(0x370, b'SIMBMS 1', 1.0)
    device.handle_frame(0x371, b'6S LFP\x00\x00', 1.0)
    device.handle_frame(0x372, bytes([4, 0, 1, 0, 0, 0, 0xFF, 0xFF]), 1.0)
    device.handle_frame(0x373, CELLS, 1.0)
    for frame_id, text in ((0x374, b'C3'), (0x375, b'C11'), (0x376, b'T1'), (0x377, b'T2')):
        device.handle_frame(frame_id, text, 1.0)
    values = device.diagnostic_report().values
    assert values['bms name'] == 'SIMBMS 16S LFP'
    assert values['modules OK'] == '4' and values['modules blocking charge'] == '1'
    assert values['modules blocking discharge'] == '0'
    assert values['modules offline'] == 'not available'
    assert values['min cell voltage V'] == '3.300' and values['max cell voltage V'] == '3.312'
    assert values['min cell temperature degC'] == '14.85'
    assert values['max cell temperature degC'] == '26.85'
    assert (values['min cell voltage id'], values['max cell voltage id']) == ('C3', 'C11')
    assert values['min cell temperature id'] == 'T1'
    assert values['max cell temperature id'] == 'T2'


def test_0x373_fills_temperature_only_where_0x356_has_none():
    device, _ = make()
    device.handle_frame(0x373, CELLS, 1.0)
    device.handle_frame(0x356, BATTERY, 1.0)
    assert device.battery_report().temperature == 25.3  # 0x356's own value wins
    device.handle_frame(0x356, BATTERY_NO_TEMP, 2.0)
    assert device.battery_report().temperature == 26.85  # the hottest cell
    device.handle_frame(0x373, bytes([0xFF] * 8), 2.0)
    assert math.isnan(device.battery_report().temperature)


def test_each_group_expires_on_its_own():
    device, clock = make()
    device.handle_frame(0x351, LIMITS, 1.0)  # tells the 0x356 voltage scale (kept after)
    device.handle_frame(0x359, bytes([0b0000_0010, 0, 0, 0, 2]), 1.0)
    device.handle_frame(0x355, bytes([0x50, 0x00, 0x62, 0x00]), 1.0)
    device.handle_frame(0x373, CELLS, 1.0)
    device.handle_frame(0x35E, b'PYLON', 1.0)
    device.handle_frame(0x356, BATTERY_NO_TEMP, 1.0)
    report = device.battery_report()
    assert report.percentage == 0.8 and report.temperature == 26.85
    assert report.power_supply_health == PowerSupplyHealth.OVERVOLTAGE
    # only 0x356 keeps coming: everything else expires after stale_timeout
    clock.now += device.stale_timeout + 0.5
    device.handle_frame(0x356, BATTERY_NO_TEMP, 2.0)
    report = device.battery_report()
    assert report.present and report.voltage == 51.23
    assert math.isnan(report.percentage) and math.isnan(report.temperature)
    assert report.power_supply_health == PowerSupplyHealth.UNKNOWN
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'alarm frame 0x359 silent for 5.5 s: alarms unknown' in diag.message
    assert diag.values['frames expired'] == (
        '0x351 (5.5 s ago), 0x355 (5.5 s ago), 0x359 (5.5 s ago), 0x373 (5.5 s ago)')
    assert 'alarms active (0x359)' not in diag.values and 'soc %' not in diag.values
    assert diag.values['manufacturer'] == 'PYLON'  # identity frames keep longer
    clock.now += IDENTITY_TIMEOUT
    device.handle_frame(0x356, BATTERY_NO_TEMP, 3.0)
    assert 'manufacturer' not in device.diagnostic_report().values
    # a fresh frame brings its group back
    device.handle_frame(0x359, bytes(5), 4.0)
    diag = device.diagnostic_report()
    assert diag.level == Level.OK and diag.values['alarms active (0x359)'] == 'none'


@pytest.mark.parametrize('frame_id, data', [
    (0x359, bytes(3)), (0x35C, b''), (0x372, bytes(7)), (0x373, bytes(9)),
    (0x373, bytes([0xF0, 0x0C, 0xE4, 0x0C, 0x20, 0x01, 0x2C, 0x01])), (0x370, b'')])
def test_malformed_dialect_frames_are_counted_and_change_nothing(frame_id, data):
    device, _ = make()
    device.handle_frame(0x356, BATTERY, 1.0)
    device.handle_frame(0x35A, ALL_OK_35A, 1.0)
    before = device.diagnostic_report().values
    assert not device.handle_frame(frame_id, data, 2.0)
    assert device.frames_malformed == 1
    after = device.diagnostic_report().values
    assert f'0x{frame_id:X}' in after.pop('last malformed frame')
    assert {k: v for k, v in after.items() if k != 'frames malformed'} == {
        k: v for k, v in before.items() if k != 'frames malformed'}
