# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""SmaDevice: frames (hand-written) -> BatteryReport and diagnostics."""
import math

import pytest

from ams_can_bridge.devices.base import Level, PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.devices.sma.device import SmaDevice
from ams_can_bridge.protocols.sma import SMA_CONDITIONS
from helpers import Clock


def make():
    clock = Clock(50.0)
    return SmaDevice('sma', {}, clock=clock), clock


def flags(alarms=(), warnings=()):
    """0x35A bytes: the named conditions ACTIVE, every other one OK."""
    data = bytearray(8)
    for k, name in enumerate(SMA_CONDITIONS):
        for first, active in ((0, alarms), (4, warnings)):
            data[first + k // 4] |= (1 if name in active else 2) << (2 * (k % 4))
    return bytes(data)


# 5123 x 0.01 V, -125 x 0.1 A (discharging), 253 x 0.1 degC
DISCHARGING = bytes([0x03, 0x14, 0x83, 0xFF, 0xFD, 0x00])
# 0x351: 55.2 V, 50 A, 100 A, 48 V: tells that 0x356 is in 0.01 V (51.23 V, not 512.3 V)
LIMITS = bytes([0x28, 0x02, 0xF4, 0x01, 0xE8, 0x03, 0xE0, 0x01])


def test_ids_and_constants():
    device, _ = make()
    assert device.TYPE == 'sma' and device.DEFAULT_BASE_ID is None
    assert device.arbitration_ids == {0x351, 0x355, 0x356, 0x35A, 0x35E, 0x35F,
                                      0x359, 0x35C, *range(0x370, 0x37A), 0x382}
    assert device.stale_timeout == 5 * device.BROADCAST_PERIOD


def test_charge_positive_wire_gives_ros_negative_while_discharging():
    device, _ = make()
    assert not device.handle_frame(0x351, LIMITS, 98.0)
    assert device.handle_frame(0x356, DISCHARGING, 99.0)
    report = device.battery_report()
    assert report.present and report.stamp == 99.0
    assert report.voltage == 51.23 and report.current == -12.5 and report.temperature == 25.3
    assert report.power_supply_status == PowerSupplyStatus.DISCHARGING
    assert math.isnan(report.percentage)
    assert report.power_supply_health == PowerSupplyHealth.UNKNOWN  # no 0x35A yet
    device.handle_frame(0x356, bytes([0x03, 0x14, 0xC8, 0x00, 0xFD, 0x00]), 100.0)
    report = device.battery_report()
    assert report.current == 20.0 and report.power_supply_status == PowerSupplyStatus.CHARGING


def test_unavailable_markers_are_nan():
    device, _ = make()
    device.handle_frame(0x356, bytes([0x00, 0x80] * 3), 1.0)
    device.handle_frame(0x355, bytes([0xFF] * 4), 1.0)
    report = device.battery_report()
    assert report.present
    assert all(math.isnan(v) for v in (report.voltage, report.current, report.temperature,
                                       report.percentage))
    assert report.power_supply_status == PowerSupplyStatus.UNKNOWN
    values = device.diagnostic_report().values
    assert values['voltage V'] == 'not available' and values['soc %'] == 'not available'


def test_percentage_prefers_high_resolution_and_capacity_from_info():
    device, _ = make()
    device.handle_frame(0x356, DISCHARGING, 1.0)
    device.handle_frame(0x355, bytes([0x50, 0x00, 0x62, 0x00]), 1.0)
    assert device.battery_report().percentage == 0.8
    device.handle_frame(0x355, bytes([0x50, 0x00, 0x62, 0x00, 0x13, 0x1F]), 1.0)
    device.handle_frame(0x35F, bytes([0x01, 0x00, 0x02, 0x01, 0xC8, 0x00]), 1.0)
    report = device.battery_report()
    assert report.percentage == pytest.approx(0.7955)
    assert report.capacity == 200.0 and report.charge == pytest.approx(159.1)


@pytest.mark.parametrize('alarms, health', [
    ((), PowerSupplyHealth.GOOD),
    (('high_voltage',), PowerSupplyHealth.OVERVOLTAGE),
    (('low_voltage',), PowerSupplyHealth.DEAD),
    (('high_temperature',), PowerSupplyHealth.OVERHEAT),
    (('low_temperature',), PowerSupplyHealth.COLD),
    (('contactor',), PowerSupplyHealth.UNSPEC_FAILURE),
    (('short_circuit', 'high_voltage'), PowerSupplyHealth.OVERVOLTAGE),
])
def test_health_and_level_from_alarms(alarms, health):
    device, _ = make()
    device.handle_frame(0x356, DISCHARGING, 1.0)
    device.handle_frame(0x35A, flags(alarms=alarms), 1.0)
    assert device.battery_report().power_supply_health == health
    diag = device.diagnostic_report()
    if alarms:
        assert diag.level == Level.ERROR
        assert diag.values['alarms active'] == ', '.join(
            n for n in SMA_CONDITIONS if n in alarms)
        assert all(n in diag.message for n in alarms)
    else:
        assert diag.level == Level.OK and diag.message.startswith('OK')


def test_warnings_are_warn_and_do_not_change_health():
    device, _ = make()
    device.handle_frame(0x356, DISCHARGING, 1.0)
    device.handle_frame(0x35A, flags(warnings=('cell_imbalance', 'high_charge_current')), 1.0)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'warnings high_charge_current, cell_imbalance' in diag.message
    assert diag.values['warning cell_imbalance'] == 'ACTIVE'
    assert device.battery_report().power_supply_health == PowerSupplyHealth.GOOD


def test_diagnostic_values_limits_soh_manufacturer_info():
    device, _ = make()
    device.handle_frame(0x356, DISCHARGING, 1.0)
    device.handle_frame(0x351, bytes([0x28, 0x02, 0xF4, 0x01, 0x00, 0x80, 0xE0, 0x01]), 1.0)
    device.handle_frame(0x355, bytes([0x50, 0x00, 0x62, 0x00]), 1.0)
    device.handle_frame(0x35E, b'PYLON   ', 1.0)
    device.handle_frame(0x35F, bytes([0x01, 0x00, 0x02, 0x01, 0xC8, 0x00]), 1.0)
    values = device.diagnostic_report().values
    assert values['charge voltage limit V'] == '55.2'
    assert values['charge current limit A'] == '50'
    assert values['discharge current limit A'] == 'not available'
    assert values['discharge voltage limit V'] == '48'
    assert values['soh %'] == '98' and values['manufacturer'] == 'PYLON'
    assert values['capacity Ah'] == '200'
    # 0x35F bytes 2-3 02 01: major 2, minor 1 (not the U16 258)
    assert values['bms version'] == '2.1 (bytes 2-3: 02 01)'
    assert values['current A (positive = charging)'] == '-12.5'


def test_only_the_battery_frame_is_primary_and_stale_follows():
    device, clock = make()
    assert not device.handle_frame(0x35A, flags(), 1.0)
    assert device.diagnostic_report().level == Level.STALE
    device.handle_frame(0x356, DISCHARGING, 1.0)
    assert device.diagnostic_report().level == Level.OK
    clock.now += device.stale_timeout + 0.1
    assert device.diagnostic_report().level == Level.STALE
    assert not device.battery_report().present


def test_malformed_frames_are_counted_and_change_nothing():
    device, _ = make()
    device.handle_frame(0x351, LIMITS, 1.0)
    device.handle_frame(0x356, DISCHARGING, 1.0)
    assert not device.handle_frame(0x356, DISCHARGING[:5], 2.0)
    assert not device.handle_frame(0x35A, b'', 2.0)
    assert device.frames_malformed == 2
    assert device.battery_report().voltage == 51.23
