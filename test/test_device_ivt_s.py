# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""IVT-S device state: ROS sign convention, NaN until known, staleness, diagnostics levels."""
import math

import pytest

from ams_can_bridge import registry
from ams_can_bridge.devices.base import Level, PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.devices.ivt_s.device import IvtSDevice
from ams_can_bridge.protocols.ivt_s import IvtMux, IvtResult, IvtSCodec
from helpers import Clock


@pytest.fixture
def clock():
    return Clock()


def make(clock, **params):
    return IvtSDevice('ivt_s', params, clock=clock)


def send(device, kind, value, counter=0, order='big', base_id=0x521, stamp=1.0e9, **bits):
    """Feed one result frame, built by hand: b0 MuxID, b1 counter | status, b2..5 value."""
    divisor = 1000 if kind <= IvtMux.U3 else 10 if kind == IvtMux.T else 1
    status = (0x10 * bits.get('ocs', 0) | 0x20 * bits.get('result_error', 0)
              | 0x40 * bits.get('measurement_error', 0) | 0x80 * bits.get('system_error', 0))
    data = bytes([kind, counter | status]) + round(value * divisor).to_bytes(
        4, order, signed=True)
    return device.handle_frame(base_id + kind, data, stamp)


def test_registry_finds_the_device_with_its_params():
    cls = registry.device_class('ivt_s')
    assert cls is IvtSDevice
    assert cls.TYPE == 'ivt_s' and cls.DEFAULT_BASE_ID == 0x521
    params = {p.key: p for p in cls.PARAMS}
    assert params['byte_order'].default == 'big'
    assert params['byte_order'].choices == ('big', 'little')
    assert params['discharge_positive'].default is True


def test_nan_and_not_present_before_any_frame(clock):
    device = make(clock)
    assert math.isnan(device.current_a())
    assert math.isnan(device.voltage_v())
    assert math.isnan(device.charge_ah())
    report = device.battery_report()
    assert not report.present
    assert math.isnan(report.voltage) and math.isnan(report.current)
    assert report.power_supply_health == PowerSupplyHealth.UNKNOWN
    diag = device.diagnostic_report()
    assert diag.level == Level.STALE and 'never heard' in diag.message
    assert diag.values['I (A)'] == 'not received'


def test_discharge_positive_true_flips_to_ros_sign(clock):
    device = make(clock)  # default: wire current positive while discharging
    assert send(device, IvtMux.I, 12.5, stamp=1234.5) is True  # the primary frame
    assert send(device, IvtMux.U1, 398.2) is False
    assert send(device, IvtMux.AS, 7200) is False
    send(device, IvtMux.T, 31.4)
    assert device.current_a() == pytest.approx(-12.5)
    assert device.voltage_v() == pytest.approx(398.2)
    assert device.charge_ah() == pytest.approx(-2.0)
    report = device.battery_report()
    assert report.present and report.stamp == 1234.5
    assert (report.current, report.voltage) == pytest.approx((-12.5, 398.2))
    # The As counter is not the charge in the battery (issue 17): NaN in BatteryState, the
    # counter under its own name in the diagnostics.
    assert math.isnan(report.charge)
    assert device.diagnostic_report().values[
        'As counter since sensor reset (Ah, negative = discharged)'] == '-2.0000'
    assert report.temperature == pytest.approx(31.4)
    assert report.power_supply_status == PowerSupplyStatus.DISCHARGING
    assert report.power_supply_health == PowerSupplyHealth.GOOD
    assert device.diagnostic_report().level == Level.OK


def test_discharge_positive_false_keeps_wire_sign(clock):
    device = make(clock, discharge_positive=False)
    send(device, IvtMux.I, 12.5)
    send(device, IvtMux.AS, -3600)
    assert device.current_a() == pytest.approx(12.5)
    assert device.charge_ah() == pytest.approx(-1.0)
    assert device.battery_report().power_supply_status == PowerSupplyStatus.CHARGING
    send(device, IvtMux.I, -40.0, counter=1)
    assert device.current_a() == pytest.approx(-40.0)
    assert device.battery_report().power_supply_status == PowerSupplyStatus.DISCHARGING


def test_discharge_positive_accepts_yaml_strings_and_refuses_others(clock):
    assert make(clock, discharge_positive='false').discharge_positive is False
    with pytest.raises(ValueError, match='discharge_positive'):
        make(clock, discharge_positive='maybe')
    with pytest.raises(ValueError, match=r"^shunt\.discharge_positive = 'maybe'"):
        IvtSDevice('shunt', {'discharge_positive': 'maybe'}, clock=clock)


def test_little_endian_and_base_id_settings(clock):
    device = make(clock, byte_order='little', base_id=0x600)
    assert device.arbitration_ids == frozenset(range(0x600, 0x608)) | {0x511}  # + answers
    assert not device.is_extended_id
    send(device, IvtMux.I, -3.25, order='little', base_id=0x600)
    assert device.current_a() == pytest.approx(3.25)
    with pytest.raises(ValueError, match="'big' | 'little'"):
        make(clock, byte_order='middle')


def test_stale_current_and_stale_voltage(clock):
    device = make(clock)
    assert device.stale_timeout == pytest.approx(0.5)  # 5 x BROADCAST_PERIOD 0.1 s
    send(device, IvtMux.I, 10.0)
    send(device, IvtMux.U1, 400.0)
    clock.now += 0.3
    send(device, IvtMux.I, 11.0, counter=1)  # the current keeps coming, U1 stops
    clock.now += 0.3
    assert device.current_a() == pytest.approx(-11.0)
    assert math.isnan(device.voltage_v())
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'result stopped (U1)' in diag.message
    clock.now += 0.3
    assert math.isnan(device.current_a())
    report = device.battery_report()
    assert not report.present and math.isnan(report.current)
    diag = device.diagnostic_report()
    assert diag.level == Level.STALE and 'silent for' in diag.message
    send(device, IvtMux.I, 9.0, counter=2)  # recovers alone
    assert device.current_a() == pytest.approx(-9.0)
    assert device.battery_report().present


def test_system_error_is_error_and_unspec_failure(clock):
    device = make(clock)
    send(device, IvtMux.I, 1.0)
    send(device, IvtMux.T, 25.0, system_error=1)
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert 'system error bit (byte 1 bit 7, System_Error' in diag.message
    assert 'on T: not used' in diag.message
    assert diag.values['T status'] == 'system error'
    assert device.battery_report().power_supply_health == PowerSupplyHealth.UNSPEC_FAILURE
    assert math.isnan(device.temperature_c())


def test_system_error_result_is_no_measurement(clock):
    # Issue 17 point 3: like the result-error bit, never a number (so never in the AMS pack).
    device = make(clock)
    send(device, IvtMux.I, 30.0, system_error=1)
    send(device, IvtMux.U1, 400.0, system_error=1)
    assert math.isnan(device.current_a()) and math.isnan(device.voltage_v())
    report = device.battery_report()
    assert math.isnan(report.current) and math.isnan(report.voltage)
    assert device.diagnostic_report().values['I raw (mA)'] == '30000'  # still shown raw
    send(device, IvtMux.I, 30.0, counter=1)  # the bit clears: a measurement again
    assert device.current_a() == pytest.approx(-30.0)


def test_each_result_expires_on_its_own_cycle(clock):
    # I every 10 ms, As every second: As is not "stopped" between its frames.
    device = make(clock)
    for n in range(301):
        send(device, IvtMux.I, 5.0, counter=n & 15)
        if n % 100 == 0:
            send(device, IvtMux.AS, 3600.0, counter=(n // 100) & 15)
        clock.now += 0.01
    clock.now += 0.7  # 0.7 s after the last As: beyond stale_timeout (0.5 s), within 5 s
    send(device, IvtMux.I, 5.0, counter=3)
    diag = device.diagnostic_report()
    assert 'result stopped' not in diag.message and diag.level == Level.OK
    assert float(diag.values['As expires after (s)']) == pytest.approx(5.0, rel=0.05)
    assert device.charge_ah() == pytest.approx(-1.0)
    clock.now += 5.0  # now it did stop
    send(device, IvtMux.I, 5.0, counter=4)
    assert 'result stopped (As)' in device.diagnostic_report().message


@pytest.mark.parametrize('bit, text', [
    ('ocs', 'over-current (OCS) tripped (I)'),
    ('measurement_error', 'measurement error (I)'),
    ('result_error', 'result error/out of range (I)')])
def test_warning_bits_name_the_result(clock, bit, text):
    device = make(clock)
    send(device, IvtMux.I, 1.0, **{bit: 1})
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and text in diag.message
    assert device.battery_report().power_supply_health == PowerSupplyHealth.GOOD


def test_result_error_makes_that_value_nan(clock):
    device = make(clock)
    send(device, IvtMux.I, 2.0)
    send(device, IvtMux.U1, 800.0, result_error=1)  # out of range: not a number to trust
    assert math.isnan(device.voltage_v())
    assert device.current_a() == pytest.approx(-2.0)
    assert device.diagnostic_report().values['U1 raw (mV)'] == '800000'  # still shown raw


def test_stuck_counter_warns(clock):
    device = make(clock)
    for _ in range(3):
        send(device, IvtMux.I, 1.0, counter=7)
        clock.now += 0.1
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'counter stuck or skipping (I)' in diag.message
    assert diag.values['I counter stuck'] == '2'


def test_jumping_counter_warns_then_recovers(clock):
    device = make(clock)
    counters = [14, 15, 0, 1]  # wraps 15 -> 0 without complaint
    for c in counters:
        send(device, IvtMux.U1, 400.0, counter=c)
        send(device, IvtMux.I, 1.0, counter=c)
        clock.now += 0.1
    assert device.diagnostic_report().level == Level.OK
    send(device, IvtMux.I, 1.0, counter=5)  # 2, 3, 4 lost
    send(device, IvtMux.U1, 400.0, counter=2)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'counter stuck or skipping (I)' in diag.message
    assert diag.values['I counter jumps'] == '1'
    for n in range(16):
        send(device, IvtMux.I, 1.0, counter=(6 + n) & 15)
        send(device, IvtMux.U1, 400.0, counter=(3 + n) & 15)
        clock.now += 0.01
    assert device.diagnostic_report().level == Level.OK


def test_counter_restart_after_silence_is_not_a_jump(clock):
    device = make(clock)
    send(device, IvtMux.I, 1.0, counter=9)
    clock.now += 2.0  # sensor rebooted
    send(device, IvtMux.I, 1.0, counter=0)
    assert device.diagnostic_report().values['I counter jumps'] == '0'


def test_malformed_frames_are_counted_and_change_nothing(clock):
    device = make(clock)
    send(device, IvtMux.I, 5.0)
    assert device.handle_frame(0x521, bytes(5), 0.0) is False  # wrong DLC
    assert device.handle_frame(0x522, bytes([0, 0, 0, 0, 0, 1]), 0.0) is False  # wrong MuxID
    assert device.current_a() == pytest.approx(-5.0)
    assert math.isnan(device.voltage_v())
    diag = device.diagnostic_report()
    assert diag.values['frames malformed'] == '2' and diag.values['frames received'] == '1'
    assert 'MuxID 0' in diag.values['last malformed frame']


def test_diagnostic_values_cover_every_result_with_units(clock):
    device = make(clock)
    codec = IvtSCodec()
    for kind in IvtMux:
        frame = codec.encode(IvtResult.from_value(kind, 10.0 + kind, counter=3))
        device.handle_frame(frame.arbitration_id, frame.data, 0.0)
    values = device.diagnostic_report().values
    for name, unit, raw_unit in [('I', 'A', 'mA'), ('U1', 'V', 'mV'), ('U2', 'V', 'mV'),
                                 ('U3', 'V', 'mV'), ('T', 'degC', '0.1 degC'), ('W', 'W', 'W'),
                                 ('As', 'As', 'As'), ('Wh', 'Wh', 'Wh')]:
        assert f'{name} ({unit})' in values and f'{name} raw ({raw_unit})' in values
        assert values[f'{name} counter'] == '3' and values[f'{name} status'] == 'ok'
    assert values['T (degC)'] == '14' and values['T raw (0.1 degC)'] == '140'
    assert values['power (W, as measured)'] == '15'
    assert values['energy (Wh, as measured)'] == '17'
    assert values['current (A, negative = discharging)'] == '-10.000'
