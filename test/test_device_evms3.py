# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""EVMS3 device state: frames written by hand in, exact BatteryState and diagnostics out."""
import math

import pytest

from ams_can_bridge.devices.base import Level, PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.devices.evms3.device import Evms3Device
from ams_can_bridge.errors import RefusedCommand
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import Evms3Error, Evms3State
from helpers import Clock

# RUNNING, no error, 100.0 Ah, 400.0 V, aux 13.0 V, isolation 100 %, 25 degC
STATUS_OK = bytes.fromhex('02 03 E8 0F A0 82 64 41')
CURRENT_10A_DISCHARGE = bytes.fromhex('80 27 10')
CURRENT_20A5_CHARGE = bytes.fromhex('7F AF EC')


def make(clock=None, **params):
    return Evms3Device('evms3', params, clock=clock or Clock(1000.0))


def status(state=2, error=0, b6=0x64, b7=0x41):
    return bytes([state | error << 3, 0x03, 0xE8, 0x0F, 0xA0, 0x82, b6, b7])


def test_class_contract():
    device = make(bms12_modules=2)
    assert (Evms3Device.TYPE, Evms3Device.BROADCAST_PERIOD, Evms3Device.DEFAULT_BASE_ID) == (
        'evms3', 0.25, 30)
    assert device.is_extended_id is True
    chargers = {0x1806E5F4, 0x1806E7F4, 0x1806E8F4, 0x18FF50E5, 0x18FF50E7, 0x18FF50E8}
    readback = set(range(52, 57))
    assert device.arbitration_ids == frozenset(
        list(range(30, 42)) + list(range(300, 305)) + list(range(310, 315))) | chargers \
        | readback
    assert make(base_id=100).arbitration_ids == frozenset(range(100, 112)) | chargers \
        | readback
    spec = {p.key: p for p in Evms3Device.PARAMS}['bms12_modules']
    assert (spec.type, spec.default, spec.low, spec.high) == (int, 0, 0, 16)
    assert device.stale_timeout == pytest.approx(1.25)


def test_exact_report_values():
    device = make(**{'config.pack_capacity_ah': 200})
    assert device.handle_frame(30, STATUS_OK, 1234.5) is True
    assert device.handle_frame(40, CURRENT_10A_DISCHARGE, 1234.6) is False
    report = device.battery_report()
    assert report.stamp == 1234.5
    assert report.voltage == 400.0
    assert report.charge == 100.0
    assert report.capacity == 200.0 and report.design_capacity == 200.0
    assert report.percentage == 0.5
    assert report.temperature == 25.0
    assert report.current == -10.0  # discharging: negative in ROS
    assert report.power_supply_status == PowerSupplyStatus.DISCHARGING
    assert report.power_supply_health == PowerSupplyHealth.GOOD
    assert report.present is True
    assert report.cell_voltage == [] and report.cell_temperature == []
    assert device.state is Evms3State.RUNNING and device.error is Evms3Error.NONE


def test_nan_before_anything_and_without_capacity():
    device = make()
    report = device.battery_report()
    assert report.present is False
    assert all(math.isnan(getattr(report, f)) for f in (
        'voltage', 'current', 'charge', 'percentage', 'temperature', 'capacity'))
    assert device.state is None and device.error is None
    device.handle_frame(30, status(b7=0), 1.0)  # temperature raw 0: no sensor
    report = device.battery_report()
    assert report.voltage == 400.0 and report.charge == 100.0
    assert math.isnan(report.percentage)  # pack capacity not configured
    assert math.isnan(report.capacity)
    assert math.isnan(report.temperature)
    assert math.isnan(report.current)  # no ID 40 yet
    assert report.power_supply_status == PowerSupplyStatus.UNKNOWN
    values = device.diagnostic_report().values
    assert values['temperature (degC)'] == 'no sensor'
    assert 'pack_capacity_ah' in values['state of charge (%)']


def test_percentage_is_clamped_to_one():
    device = make(**{'config.pack_capacity_ah': 50})  # 100 Ah remaining > 50 Ah capacity
    device.handle_frame(30, STATUS_OK, 1.0)
    assert device.battery_report().percentage == 1.0


def test_current_sign_and_charging_state():
    device = make()
    device.handle_frame(30, STATUS_OK, 1.0)
    device.handle_frame(40, CURRENT_20A5_CHARGE, 1.0)
    report = device.battery_report()
    assert report.current == pytest.approx(20.5)
    assert report.power_supply_status == PowerSupplyStatus.CHARGING
    device.handle_frame(30, status(state=3), 1.0)
    device.handle_frame(40, CURRENT_10A_DISCHARGE, 1.0)
    # the EVMS state wins over a momentary discharge reading while charging
    assert device.battery_report().power_supply_status == PowerSupplyStatus.CHARGING
    device.handle_frame(30, status(state=0), 1.0)
    device.handle_frame(40, bytes.fromhex('80 00 00'), 1.0)
    assert device.battery_report().power_supply_status == PowerSupplyStatus.NOT_CHARGING


def test_current_goes_nan_when_old():
    clock = Clock(1000.0)
    device = make(clock)
    device.handle_frame(40, CURRENT_10A_DISCHARGE, 1.0)
    clock.now += 1.0
    device.handle_frame(30, STATUS_OK, 2.0)
    assert device.battery_report().current == -10.0
    clock.now += 0.5  # 1.5 s since the current, status still fresh
    device.handle_frame(30, STATUS_OK, 2.5)
    report = device.battery_report()
    assert report.present is True and math.isnan(report.current)
    assert device.diagnostic_report().values['current (A, discharge negative)'].startswith(
        'not received')


@pytest.mark.parametrize('error,health,level', [
    (0, PowerSupplyHealth.GOOD, Level.OK),
    (2, PowerSupplyHealth.GOOD, Level.WARN),
    (4, PowerSupplyHealth.GOOD, Level.WARN),
    (10, PowerSupplyHealth.GOOD, Level.WARN),
    (6, PowerSupplyHealth.OVERVOLTAGE, Level.WARN),
    (7, PowerSupplyHealth.OVERVOLTAGE, Level.ERROR),
    (5, PowerSupplyHealth.DEAD, Level.ERROR),
    (8, PowerSupplyHealth.OVERHEAT, Level.ERROR),
    (11, PowerSupplyHealth.OVERHEAT, Level.ERROR),
    (9, PowerSupplyHealth.COLD, Level.ERROR),
    (1, PowerSupplyHealth.UNSPEC_FAILURE, Level.ERROR),
    (3, PowerSupplyHealth.UNSPEC_FAILURE, Level.ERROR),
    (12, PowerSupplyHealth.UNSPEC_FAILURE, Level.ERROR),
    (16, PowerSupplyHealth.UNSPEC_FAILURE, Level.ERROR),
])
def test_health_and_level_from_error_code(error, health, level):
    device = make()
    device.handle_frame(30, status(error=error), 1.0)
    assert device.battery_report().power_supply_health == health
    diag = device.diagnostic_report()
    assert diag.level == level
    assert diag.values['error code'] == str(error)
    assert device.error == error


def test_diagnostic_message_and_values():
    device = make()
    device.handle_frame(30, status(state=4, error=12, b6=0xE5), 1.0)  # isolation 101
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert diag.message == 'STOPPED, error ISOLATION_ERROR (12)'
    assert diag.values['isolation (%)'] == 'not measured'
    assert diag.values['headlights'] == 'on'
    assert diag.values['pack voltage (V)'] == '400.0'
    assert diag.values['aux voltage (V)'] == '13.0'
    device.handle_frame(30, status(state=2, error=4), 1.0)
    diag = device.diagnostic_report()
    assert (diag.level, diag.message) == (Level.WARN, 'RUNNING, warning LOW_CELL_WARNING (4)')


def test_stale_status():
    clock = Clock(1000.0)
    device = make(clock)
    assert device.diagnostic_report().level == Level.STALE
    device.handle_frame(30, STATUS_OK, 1.0)
    assert device.diagnostic_report().level == Level.OK
    clock.now += 1.3  # default stale_timeout 5 x 0.25 s
    assert device.diagnostic_report().level == Level.STALE
    assert device.battery_report().present is False


def test_malformed_frames_are_counted_not_applied():
    device = make()
    device.handle_frame(30, STATUS_OK, 1.0)
    assert device.handle_frame(30, bytes([6, 0, 0, 0, 0, 0, 0, 0]), 2.0) is False
    assert device.handle_frame(40, b'\x80', 2.0) is False
    assert device.frames_malformed == 2
    assert device.battery_report().voltage == 400.0
    assert 'DLC 1, expected 3' in device.diagnostic_report().values['last malformed frame']


def cells_frame(first_mv, count=4):
    return b''.join((first_mv + i).to_bytes(2, 'big') for i in range(count))


def test_bms12_cells_nan_until_received():
    clock = Clock(1000.0)
    device = make(clock, bms12_modules=2)
    device.handle_frame(30, STATUS_OK, 1.0)
    assert len(device.battery_report().cell_voltage) == 24
    assert all(math.isnan(v) for v in device.battery_report().cell_voltage)
    device.handle_frame(311, cells_frame(3300), 1.0)  # module 1, cells 1..4
    device.handle_frame(302, cells_frame(4000), 1.0)  # module 0, cells 5..8
    device.handle_frame(314, bytes([65, 0, 0, 0, 0, 0, 0, 0]), 1.0)
    cells = device.battery_report().cell_voltage
    assert cells[4:8] == [4.0, 4.001, 4.002, 4.003]
    assert cells[12:16] == [3.3, 3.301, 3.302, 3.303]
    assert sum(1 for v in cells if not math.isnan(v)) == 8
    values = device.diagnostic_report().values
    assert values['module 1 cells'] == '4/12 received'
    assert values['module 1 cell min (V)'] == '3.300'
    assert values['module 1 cell max (V)'] == '3.303'
    # raw 0 = no sensor (BMS12 firmware LineariseTemp), never -40 degC
    assert values['module 1 temperatures (degC)'] == '25, no sensor'
    assert values['module 0 temperatures (degC)'] == 'unknown, unknown'


def test_cells_per_module_from_config():
    device = make(bms12_modules=2, **{'config.cells_per_module': [4, 9] + [0] * 14})
    device.handle_frame(30, STATUS_OK, 1.0)
    for aid, mv in ((301, 3000), (302, 3100), (311, 3200), (312, 3300), (313, 3400)):
        device.handle_frame(aid, cells_frame(mv), 1.0)
    cells = device.battery_report().cell_voltage
    assert cells == [3.0, 3.001, 3.002, 3.003,
                     3.2, 3.201, 3.202, 3.203, 3.3, 3.301, 3.302, 3.303, 3.4]


def test_silent_module_warns_and_its_cells_become_unknown():
    clock = Clock(1000.0)
    device = make(clock, bms12_modules=2)
    for t in range(4):
        device.handle_frame(30, STATUS_OK, clock.now)
        for aid in (301, 302, 303, 311, 312, 313):
            if t == 0 or aid < 310:  # module 1 answers only once
                device.handle_frame(aid, cells_frame(3500), clock.now)
        clock.now += 1.0
    device.handle_frame(30, STATUS_OK, clock.now)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert diag.message == 'RUNNING, no error; BMS12 module(s) silent: 1'
    cells = device.battery_report().cell_voltage
    assert not any(math.isnan(v) for v in cells[:12])
    assert all(math.isnan(v) for v in cells[12:])


def test_the_device_builds_its_command_frames_and_refuses_an_ack_it_cannot_back():
    clock = Clock(1000.0)
    device = make(clock)
    with pytest.raises(RefusedCommand, match='stale'):
        device.ack_frame()
    device.handle_frame(30, status(), 1.0)
    with pytest.raises(RefusedCommand, match='no error to acknowledge'):
        device.ack_frame()
    device.handle_frame(30, status(error=12), 1.0)
    ack = device.ack_frame()
    assert (ack.arbitration_id, ack.data, ack.is_extended_id) == (37, b'\x0c', True)
    assert device.reset_soc_frame() == Frame(38, b'', True)
    assert device.setup_mode_frame(True) == Frame(31, b'\x01', True)
    short = make(clock, extended_id=False)
    assert short.setup_mode_frame(False) == Frame(31, b'\x00', False)
    assert device.optional_config(device.config.replace({'config.balance_mode': 'dynamic'})) \
        == ('balance_v',)
    assert device.optional_config(device.config.replace({'config.balance_mode': 'fixed'})) == ()


# --- issue 17 "Field truth": EVMS3 firmware and ZEVA Monitor facts --------------------------
FULL_CONFIG = {
    'pack_capacity_ah': 100, 'soc_warning_pct': 20, 'full_voltage_v': 400,
    'warn_current_a': 300, 'trip_current_a': 500, 'temp_warning_c': 60,
    'min_aux_voltage_v': 16, 'min_isolation_pct': 50, 'tacho_ppr': 2,
    'fuel_gauge_full_pct': 90, 'fuel_gauge_empty_pct': 10, 'temp_gauge_hot_pct': 80,
    'temp_gauge_cold_pct': 20, 'bms_min_cell_v': 2.8, 'bms_max_cell_v': 3.65,
    'balance_v': 3.5, 'balance_mode': 'static', 'bms_hysteresis_v': 0.05,
    'bms_min_temp_c': 0, 'bms_max_temp_c': 55, 'max_charge_voltage_v': 300,
    'max_charge_current_a': 30, 'alt_charge_voltage_v': 250, 'alt_charge_current_a': 10,
    'sleep_delay_min': 6, 'mpi_function': 1, 'mpo1_function': 2, 'mpo2_function': 6,
    'parallel_strings': 2, 'enable_precharge': True, 'stationary_mode': False,
    'reverse_current_display': True, 'night_brightness': 7,
    'cells_per_module': [12, 8] + [0] * 14,
}
# Written by hand: the Monitor's order (EVMS_Monitor3.c TransmitSettings) 36, 32, 33, 34, 35
FULL_CONFIG_FRAMES = [
    Frame(36, bytes.fromhex('8C 00 00 00 00 00 00 00'), True),  # 12 | 8 << 4
    Frame(32, bytes.fromhex('14 14 C8 1E 32 3C 10 32'), True),  # aux 16 V (Common.h max)
    Frame(33, bytes.fromhex('02 5A 0A 50 14 82 A5 96'), True),
    Frame(34, bytes.fromhex('05 28 5F 2C 9E FA 0A 06'), True),  # sleep 6 = never
    Frame(35, bytes.fromhex('01 02 06 02 01 00 01 07'), True),  # settings 30, 31 = 1, 7
]


def configured(clock=None, **params):
    return make(clock, **{**{f'config.{k}': v for k, v in FULL_CONFIG.items()}, **params})


@pytest.mark.parametrize('state', [0, 5])
def test_write_in_the_monitors_order_while_idle_or_setup(state):
    device = configured()
    device.handle_frame(30, status(state=state), 1.0)
    assert device.config_frames() == FULL_CONFIG_FRAMES


@pytest.mark.parametrize('state,name', [
    (1, 'PRECHARGING'), (2, 'RUNNING'), (3, 'CHARGING'), (4, 'STOPPED')])
def test_write_refused_in_any_other_state_naming_it(state, name):
    device = configured()
    device.handle_frame(30, status(state=state), 1.0)
    with pytest.raises(RefusedCommand,
                       match=f'reports {name}: .* only while it reports IDLE or SETUP'):
        device.config_frames()


def test_write_refused_when_never_heard_or_stale():
    clock = Clock(1000.0)
    device = configured(clock)
    with pytest.raises(RefusedCommand, match='never heard'):
        device.config_frames()
    device.handle_frame(30, status(state=0), 1.0)
    clock.now += 2.0
    with pytest.raises(RefusedCommand, match='stale .*last state IDLE'):
        device.config_frames()


def test_min_aux_voltage_16_and_cells_per_module_limits():
    # Common.h maximums[MIN_AUX_VOLTAGE] = 16; cells 0 or 4..12 a module
    device = configured()
    assert device.config_reason('config.min_aux_voltage_v', 16) is None
    assert 'refused' in device.config_reason('config.min_aux_voltage_v', 17)
    for bad in (13, 15, 3):
        reason = device.config_reason('config.cells_per_module', [12, bad] + [0] * 14)
        assert reason and 'cells_per_module' in reason and 'refused' in reason, reason
    assert device.config_reason('config.cells_per_module', [4, 12] + [0] * 14) is None


@pytest.mark.parametrize('error,health,level,action', [
    (4, PowerSupplyHealth.DEAD, Level.ERROR, 'main contactor opened (stationary mode)'),
    (6, PowerSupplyHealth.OVERVOLTAGE, Level.WARN, 'charging disabled (stationary mode)'),
])
def test_stationary_mode_warnings_say_what_the_evms_did(error, health, level, action):
    # EVMS3 firmware, stationary version: BMS_LOW_WARNING clears MAIN_CTR, BMS_HIGH_WARNING
    # clears CHARGE_ENABLE
    device = make(**{'config.stationary_mode': True})
    device.handle_frame(30, status(state=2, error=error), 1.0)
    assert device.battery_report().power_supply_health == health
    diag = device.diagnostic_report()
    assert diag.level == level
    assert diag.message.endswith(action), diag.message
    assert diag.values['stationary mode'] == 'yes'
    vehicle = make(**{'config.stationary_mode': False})
    vehicle.handle_frame(30, status(state=2, error=4), 1.0)
    assert vehicle.battery_report().power_supply_health == PowerSupplyHealth.GOOD
    assert vehicle.diagnostic_report().message == 'RUNNING, warning LOW_CELL_WARNING (4)'


def test_stationary_mode_from_a_read_back_seen_on_the_bus():
    from shared import EVMS3_ANSWER as ANSWER
    device = make()
    device.handle_frame(30, status(state=2, error=4), 1.0)
    assert device.diagnostic_report().values['stationary mode'] == 'unknown'
    for frame_id, data in {**ANSWER, 55: bytes.fromhex('01 02 06 02 01 01 01 07')}.items():
        device.handle_frame(frame_id, data, 1.0)
    assert device.battery_report().power_supply_health == PowerSupplyHealth.DEAD
    assert 'main contactor opened' in device.diagnostic_report().message


def test_bms16_marker_is_named_and_refuses_a_write():
    # EVMS_Monitor3.c: ID 30 with evmsStatusBytes[5] == 255 -> isBMS16
    device = configured()
    device.handle_frame(30, bytes.fromhex('00 03 E8 0F A0 FF 64 41'), 1.0)  # IDLE, byte 5 255
    diag = device.diagnostic_report()
    assert diag.message.startswith('BMS16 marker heard (ID 30 byte 5 = 255)')
    assert diag.level == Level.WARN
    assert diag.values['aux voltage (V)'] == 'n/a (255: BMS16 marker)'
    with pytest.raises(RefusedCommand, match='BMS16'):
        device.config_frames()


def test_voltage_multiplier_2_scales_the_full_and_charge_voltages():
    # Common.h PACK_VOLTAGE_MULTIPLIER 2 (800 V builds): full voltage 4 V a step
    device = configured(voltage_multiplier=2, **{'config.full_voltage_v': 800,
                                                 'config.max_charge_voltage_v': 600})
    device.handle_frame(30, status(state=0), 1.0)
    frames = device.config_frames()
    assert frames[1].data[2] == 200 and frames[3].data[3:5] == bytes([0x2C, 0x9E])
    assert 'refused' in device.config_reason('config.full_voltage_v', 802)
    assert 'refused' in make().config_reason('config.full_voltage_v', 800)
