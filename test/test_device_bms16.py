# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Bms16Device: frames (hand-written) -> BatteryReport and diagnostics."""
import math

import pytest

from ams_can_bridge.devices.base import Level, PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.devices.bms16.inverter import Bms16Device
from ams_can_bridge.errors import RefusedCommand
from ams_can_bridge.protocols.bms16 import Bms16Error
from helpers import Clock


def status(error=0, soc=80, deci_volts=528, deci_amps=125, temp=25):
    """Status frame bytes; deci_amps on the wire sign (positive = discharge)."""
    raw = 32768 + deci_amps
    return bytes([error, soc, deci_volts & 0xFF, deci_volts >> 8, raw & 0xFF, raw >> 8, temp])


def make(params=None):
    clock = Clock()
    return Bms16Device('pack', params or {}, clock=clock), clock


def test_ids_and_constants():
    device, _ = make()
    assert device.TYPE == 'bms16' and device.BROADCAST_PERIOD == 0.25
    assert device.DEFAULT_BASE_ID == 500
    assert device.arbitration_ids == {500, 501, 502, 503,
                                      0x351, 0x355, 0x356, 0x35A, 0x35E, 0x35F}
    moved, _ = make({'base_id': 0x200})
    assert {0x200, 0x203} <= moved.arbitration_ids and 500 not in moved.arbitration_ids


def test_nothing_received_is_unknown_and_not_present():
    device, _ = make()
    report = device.battery_report()
    assert not report.present
    assert math.isnan(report.voltage) and math.isnan(report.current)
    assert len(report.cell_voltage) == 16 and all(map(math.isnan, report.cell_voltage))
    assert report.power_supply_health == PowerSupplyHealth.UNKNOWN
    assert device.diagnostic_report().level == Level.STALE
    assert device.error == Bms16Error.NONE


def test_discharge_on_the_wire_is_negative_in_ros():
    device, _ = make()
    assert device.handle_frame(500, status(deci_amps=125), 1234.5)
    report = device.battery_report()
    assert report.present and report.stamp == 1234.5
    assert report.voltage == 52.8
    assert report.current == -12.5
    assert report.power_supply_status == PowerSupplyStatus.DISCHARGING
    assert report.percentage == 0.8
    assert report.temperature == 25.0
    assert report.power_supply_health == PowerSupplyHealth.GOOD
    assert math.isnan(report.capacity) and math.isnan(report.charge)


@pytest.mark.parametrize('deci_amps, current, state', [
    (-200, 20.0, PowerSupplyStatus.CHARGING), (0, 0.0, PowerSupplyStatus.NOT_CHARGING)])
def test_charge_and_idle(deci_amps, current, state):
    device, _ = make()
    device.handle_frame(500, status(deci_amps=deci_amps), 1.0)
    report = device.battery_report()
    assert report.current == current and math.copysign(1, report.current) == 1
    assert report.power_supply_status == state


def test_cells_nan_until_received_and_count_from_config():
    device, _ = make()
    device.handle_frame(500, status(), 1.0)
    device.handle_frame(501, bytes([0x4A, 0x4B, 0x4C, 0x4D, 0x4E, 0x4F, 0b1]), 1.0)
    cells = device.battery_report().cell_voltage
    assert cells[:6] == [3.30, 0.75, 0.76, 0.77, 0.78, 0.79]
    assert len(cells) == 16 and all(map(math.isnan, cells[6:]))
    device.handle_frame(503, bytes([0x40, 0x41, 0x42, 0x43, 0, 0, 0b1111]), 1.0)
    assert device.battery_report().cell_voltage[12:] == [3.20, 3.21, 3.22, 3.23]
    twelve, _ = make({'config.cells': 12, 'config.pack_capacity_ah': 100.0})
    twelve.handle_frame(500, status(soc=40), 1.0)
    twelve.handle_frame(502, bytes([0x40] * 6 + [0x3F]), 1.0)
    report = twelve.battery_report()
    assert len(report.cell_voltage) == 12 and report.cell_voltage[6:] == [3.20] * 6
    assert report.capacity == 100.0 and report.charge == pytest.approx(40.0)


def test_unset_config_cells_means_16():
    device, _ = make({'config.cells': None})
    assert len(device.battery_report().cell_voltage) == 16


@pytest.mark.parametrize('error, health', [
    (0, PowerSupplyHealth.GOOD), (1, PowerSupplyHealth.UNSPEC_FAILURE),
    (2, PowerSupplyHealth.DEAD), (3, PowerSupplyHealth.OVERVOLTAGE),
    (4, PowerSupplyHealth.UNSPEC_FAILURE), (5, PowerSupplyHealth.UNSPEC_FAILURE),
    (6, PowerSupplyHealth.UNSPEC_FAILURE), (7, PowerSupplyHealth.OVERHEAT),
    (8, PowerSupplyHealth.DEAD)])
def test_health_and_level_from_every_error(error, health):
    device, _ = make()
    device.handle_frame(500, status(error=error), 1.0)
    assert device.battery_report().power_supply_health == health
    assert device.error == Bms16Error(error)
    diag = device.diagnostic_report()
    name = Bms16Error(error).name
    if error == 0:
        assert diag.level == Level.OK and diag.message.startswith('OK')
    elif error in (4, 5):
        assert diag.level == Level.WARN and f'warning {name}' in diag.message
    else:
        assert diag.level == Level.ERROR and f'error {name}' in diag.message
    assert diag.values['error'] == name and diag.values['error code'] == str(error)


def test_diagnostic_values_cover_every_field():
    device, _ = make({'config.cells': 12})
    device.handle_frame(500, status(deci_amps=-50), 1.0)
    device.handle_frame(501, bytes([0x4A] * 6 + [1]), 1.0)
    values = device.diagnostic_report().values
    assert values['soc %'] == '80' and values['voltage V'] == '52.8'
    assert values['current A (wire, positive = discharge)'] == '-5'
    assert values['temperature degC'] == '25'
    assert values['cell 1 V'] == '3.3' and values['cell 2 V'] == '0.74'
    assert values['cell 12 V'] == 'nan' and 'cell 13 V' not in values
    assert values['cell min V'] == '0.74' and values['cell max V'] == '3.3'
    assert values['frames received'] == '2'


def test_sma_frames_feed_diagnostics():
    device, _ = make()
    device.handle_frame(500, status(), 1.0)
    device.handle_frame(0x351, bytes([0x28, 0x02, 0x10, 0x27, 0x10, 0x27, 0xC0, 0x01]), 1.0)
    device.handle_frame(0x355, bytes([0x50, 0x00, 0x64, 0x00]), 1.0)
    device.handle_frame(0x35A, bytes([0b1010_0101, 0b1000_0000]), 1.0)
    diag = device.diagnostic_report()
    assert diag.values['sma charge voltage limit V'] == '55.2'
    assert diag.values['sma charge current limit A'] == '1000'
    assert diag.values['sma discharge voltage limit V'] == '44.8'
    assert diag.values['sma soh %'] == '100'
    assert diag.values['sma alarms active'] == 'general, high_voltage'
    assert diag.values['sma alarm low_voltage'] == 'OK'
    # An active SMA alarm is an ERROR even while the status frame shows no error.
    assert diag.level == Level.ERROR and 'SMA alarms general, high_voltage' in diag.message
    # SMA frames are not the primary frame: they never count as a status.
    assert not device.handle_frame(0x356, bytes(6), 2.0)


def test_stale_after_timeout_and_fresh_again():
    device, clock = make()
    device.handle_frame(500, status(), 1.0)
    clock.now += 1.0
    assert device.battery_report().present
    clock.now += 0.5  # past 5 x 0.25 s
    assert not device.battery_report().present
    diag = device.diagnostic_report()
    assert diag.level == Level.STALE and 'silent for 1.5 s' in diag.message
    device.handle_frame(500, status(), 3.0)
    assert device.battery_report().present


def test_malformed_frames_are_counted_and_change_nothing():
    device, _ = make()
    device.handle_frame(500, status(soc=80), 1.0)
    assert not device.handle_frame(500, status(soc=10)[:6], 2.0)
    assert not device.handle_frame(0x356, b'', 2.0)
    assert not device.handle_frame(500, status(error=9), 2.0)
    assert device.frames_malformed == 3 and device.frames_received == 1
    assert device.battery_report().percentage == 0.8
    assert 'error code 9' in device.diagnostic_report().values['last malformed frame']


def test_each_cell_frame_and_sma_frame_expires_on_its_own():
    device, clock = make()
    device.handle_frame(500, status(), 1.0)
    device.handle_frame(501, bytes([0x4A] * 6 + [0]), 1.0)
    device.handle_frame(0x351, bytes([0x28, 0x02, 0x10, 0x27, 0x10, 0x27, 0xC0, 0x01]), 1.0)
    device.handle_frame(0x35A, bytes([0b1010_0101, 0b1000_0000]), 1.0)
    clock.now += 1.0
    device.handle_frame(500, status(), 2.0)
    device.handle_frame(502, bytes([0x40] * 6 + [0x3F]), 2.0)
    assert device.battery_report().cell_voltage[:6] == [0.74] * 6  # 1.0 s old: still fresh
    clock.now += 0.5  # 1.5 s after cells 1..6 and the SMA frames, only 0.5 s after the rest
    device.handle_frame(500, status(), 2.5)  # the status frame keeps coming
    report = device.battery_report()
    assert report.present
    assert all(map(math.isnan, report.cell_voltage[:6]))  # their frame stopped
    assert report.cell_voltage[6:12] == [3.20] * 6
    diag = device.diagnostic_report()
    assert diag.values['cell 1 V'] == 'nan' and diag.values['cell min V'] == '3.2'
    assert 'sma charge voltage limit V' not in diag.values
    # an expired SMA alarm is unknown, not still active
    assert diag.level == Level.OK and 'SMA alarms' not in diag.message
    device.handle_frame(501, bytes([0x4A] * 6 + [0]), 2.5)
    assert device.battery_report().cell_voltage[:6] == [0.74] * 6


@pytest.mark.parametrize('data,reason', [
    (status(soc=101), 'SoC 101 %'),
    (status(soc=186), 'SoC 186 %'),
])
def test_status_outside_the_documented_range_is_malformed(data, reason):
    device, _ = make()
    device.handle_frame(500, status(soc=100), 1.0)
    assert device.battery_report().percentage == 1.0
    assert not device.handle_frame(500, data, 2.0)
    assert device.frames_malformed == 1
    assert device.battery_report().percentage == 1.0  # never published as 1.01 / 1.86
    assert reason in device.last_malformed


def test_the_device_builds_its_command_frames_at_its_base_id():
    device, _ = make({'base_id': 0x200})
    assert [device.ack_frame().arbitration_id, device.reset_soc_frame().arbitration_id,
            device.power_off_frame().arbitration_id] == [0x206, 0x207, 0x208]
    assert device.reset_soc_frame().data == b''
    config = dict(cells=16, pack_capacity_ah=100.0, soc_warning_pct=20.0, full_voltage_v=58.0,
                  warn_current_a=100.0, trip_current_a=200.0, temperature_limit_c=60.0,
                  min_cell_v=3.0, max_cell_v=4.2, hysteresis_v=0.1, balance_v=4.0,
                  shunt_size_a=200)
    with pytest.raises(RefusedCommand, match=r'12 configuration value\(s\) unset: pack\.config'):
        device.config_frames()
    device.configure({'config.' + key: value for key, value in config.items()})
    frames = device.config_frames()
    assert [f.arbitration_id for f in frames] == [0x204, 0x205]
    assert frames[0].data == bytes([16, 10, 20, 58, 10, 20, 60, 60])
    assert frames[1].data == bytes([84, 2, 80, 2])


def test_a_base_id_overlapping_the_sma_ids_names_the_instance():
    with pytest.raises(ValueError, match=r'^front\.base_id = 848 overlaps the SMA IDs'):
        Bms16Device('front', {'base_id': 0x350})
