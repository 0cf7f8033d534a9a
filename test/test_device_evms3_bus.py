# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What else is on an EVMS3 bus: TC chargers (29-bit) and the EVMS's balance requests.

Frames written by hand; the evms3 device shows them in its diagnostics with ZEVA Monitor
names, warns on any charger status bit, and lets each group expire on its own.
"""
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.evms3.device import CHARGER_STALE_TIMEOUT, Evms3Device
from helpers import Clock

# RUNNING, no error, 100.0 Ah, 400.0 V, aux 13.0 V, isolation 100 %, 25 degC
STATUS_OK = bytes.fromhex('02 03 E8 0F A0 82 64 41')
CHARGING = bytes.fromhex('03 03 E8 0F A0 82 64 41')
# charger 1 command: 403.2 V, 12.5 A, charge
COMMAND_1 = bytes([0x0F, 0xC0, 0x00, 0x7D, 0x00, 0, 0, 0])
# charger 1 answer: 398.7 V, 9.8 A, no status bit, temperature raw 0x41
STATUS_1 = bytes([0x0F, 0x93, 0x00, 0x62, 0x00, 0x41, 0, 0])
EXPECTED_1 = {
    'charger 1 target volts (V)': '403.2', 'charger 1 target amps (A)': '12.5',
    'charger 1 shutdown by BMS': 'no', 'charger 1 output volts (V)': '398.7',
    'charger 1 output amps (A)': '9.8', 'charger 1 status': 'OK',
    'charger 1 hardware failure': 'no', 'charger 1 over-temperature shutdown': 'no',
    'charger 1 input (AC) voltage error': 'no', 'charger 1 battery fault / no battery': 'no',
    'charger 1 communication timeout': 'no', 'charger 1 temperature (raw)': '65',
    'charger 1 last heard': '0.0 s ago',
}


def make(clock=None, **params):
    return Evms3Device('evms3', params, clock=clock or Clock(1000.0))


def test_charger_command_and_answer_with_zeva_monitor_names():
    device = make()
    device.handle_frame(30, CHARGING, 1.0)
    assert device.handle_frame(0x1806E5F4, COMMAND_1, 1.0) is False  # not primary
    device.handle_frame(0x18FF50E5, STATUS_1, 1.0)
    diag = device.diagnostic_report()
    assert {k: v for k, v in diag.values.items() if k.startswith('charger')} == EXPECTED_1
    assert diag.level == Level.OK and diag.message == 'CHARGING, no error'


def test_shutdown_by_bms_and_other_chargers():
    device = make()
    device.handle_frame(30, CHARGING, 1.0)
    device.handle_frame(0x1806E8F4, COMMAND_1[:4] + b'\x01\x00\x00\x00', 1.0)  # charger 3
    values = device.diagnostic_report().values
    assert values['charger 3 shutdown by BMS'] == 'yes'
    assert 'charger 3 output volts (V)' not in values  # no answer from it yet
    assert not any(k.startswith(('charger 1', 'charger 2')) for k in values)


def test_any_charger_status_bit_warns_and_names_it():
    device = make()
    device.handle_frame(30, STATUS_OK, 1.0)
    device.handle_frame(0x18FF50E7, STATUS_1[:4] + bytes([0b0001_1000, 0x41]), 1.0)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert diag.message == ('RUNNING, no error; charger 2: battery fault / no battery, '
                            'communication timeout')
    assert diag.values['charger 2 battery fault / no battery'] == 'yes'
    assert diag.values['charger 2 communication timeout'] == 'yes'
    assert diag.values['charger 2 hardware failure'] == 'no'
    device.handle_frame(0x18FF50E7, STATUS_1[:4] + bytes([0b0100_0000]), 2.0)  # undefined bit
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and diag.message.endswith('charger 2: bit 6')
    device.handle_frame(0x18FF50E7, STATUS_1, 3.0)
    assert device.diagnostic_report().level == Level.OK


def test_charger_values_expire_on_their_own():
    clock = Clock(1000.0)
    device = make(clock)
    device.handle_frame(0x1806E5F4, COMMAND_1, 1.0)
    device.handle_frame(0x18FF50E5, STATUS_1[:4] + b'\x01\x41', 1.0)  # hardware failure
    clock.now += CHARGER_STALE_TIMEOUT + 0.5
    device.handle_frame(30, STATUS_OK, 2.0)  # the EVMS itself keeps talking
    diag = device.diagnostic_report()
    assert diag.level == Level.OK  # an old fault is not a current one
    assert {k: v for k, v in diag.values.items() if k.startswith('charger')} == {
        'charger 1 last heard': '5.5 s ago'}


def test_balance_target_per_module():
    clock = Clock(1000.0)
    device = make(clock, bms12_modules=3)
    device.handle_frame(30, STATUS_OK, 1.0)
    device.handle_frame(300, bytes([0x10, 0x09]), 1.0)  # module 0: 4105 mV
    device.handle_frame(310, bytes([0x00, 0x00]), 1.0)  # module 1: off
    values = device.diagnostic_report().values
    assert values['module 0 balance target (mV)'] == '4105'
    assert values['module 1 balance target (mV)'] == 'off'
    assert values['module 2 balance target (mV)'] == 'unknown (no request from the EVMS)'
    clock.now += device.module_timeout + 0.1
    device.handle_frame(30, STATUS_OK, 2.0)
    values = device.diagnostic_report().values
    assert values['module 0 balance target (mV)'] == 'unknown (no request from the EVMS)'


def test_a_discharging_charger_shows_a_negative_current():
    # TC protocol 1430: bit 15 of the output current marks discharging (0x8062: 9.8 A)
    device = make()
    device.handle_frame(30, CHARGING, 1.0)
    device.handle_frame(0x18FF50E5, STATUS_1[:2] + bytes([0x80]) + STATUS_1[3:], 1.0)
    assert device.diagnostic_report().values['charger 1 output amps (A)'] == '-9.8'


def test_dispatch_by_id_and_width_for_an_11_bit_evms3():
    params = {'evms3.extended_id': False, 'evms3.bms12_modules': 1}
    devices = DeviceSet(['evms3'], lambda name, spec: params.get(name, spec.default),
                        clock=Clock(1000.0))
    evms3 = devices.devices['evms3']
    assert (30, False) in devices.filters and (0x18FF50E5, True) in devices.filters
    assert (30, True) not in devices.filters
    assert devices.handle_frame(30, STATUS_OK, True, 1.0) == []  # 29-bit 30: not the EVMS3
    assert evms3.frames_received == 0
    assert devices.handle_frame(30, STATUS_OK, False, 1.0) == [evms3]
    assert devices.handle_frame(0x18FF50E5, STATUS_1, True, 1.0) == []
    assert devices.handle_frame(0x18FF50E5, STATUS_1, False, 1.0) == []  # 11-bit: no such ID
    assert evms3.frames_received == 2
    assert evms3.diagnostic_report().values['charger 1 output amps (A)'] == '9.8'
    default = DeviceSet(['evms3'], lambda name, spec: spec.default)
    assert (30, True) in default.filters and (30, False) not in default.filters
