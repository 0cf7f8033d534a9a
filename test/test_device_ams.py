# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""AMS device state: frames in (built by hand from the spec) -> exact reports out."""
import math

import pytest

from ams_can_bridge import registry
from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.devices.base import Level, PowerSupplyHealth, PowerSupplyStatus
from ams_can_bridge.devices.ivt_s.device import IvtSDevice
from ams_can_bridge.errors import RefusedCommand
from ams_can_bridge.protocols.ams import AmsError, AmsState, ChargerStart
from ams_can_bridge.protocols.common import Frame
from helpers import Clock

STAMP = 1.7e9


@pytest.fixture
def clock():
    return Clock(50.0)


def make(clock, **params):
    return AmsDevice('ams', params, clock=clock)


def status(device, state=AmsState.DRIVE, counter=0, flags=0xC0, banks=1, volt_min=180,
           temp_max=35, soc=77, relay_error=0, base=0x300):
    """AMS status 0x000: b0 = status bits 15..8, b1 = bank count << 5 | state, ..."""
    data = bytes([flags, banks << 5 | state, volt_min, temp_max, soc, counter, relay_error])
    return device.handle_frame(base, data, STAMP)


def cells(device, bank, group, raw=(180,) * 7):
    """Cell voltages 0x011: b0 = bank << 5 | group, then 7 x 20 mV."""
    return device.handle_frame(0x311, bytes([bank << 5 | group, *raw]), STAMP)


def temps(device, bank, group, values=(20,) * 5):
    return device.handle_frame(0x312, bytes([bank << 5 | group]) + bytes(
        v & 0xFF for v in values), STAMP)


def discharge(device, bank, group, values=(30,) * 7):
    return device.handle_frame(0x313, bytes([bank << 5 | group]) + bytes(
        v & 0xFF for v in values), STAMP)


def error(device, code, tick=0x0102):
    return device.handle_frame(0x314, bytes([code, tick >> 8, tick & 0xFF]), STAMP)


def test_registry_and_params():
    cls = registry.device_class('ams')
    assert cls is AmsDevice and cls.TYPE == 'ams' and cls.DEFAULT_BASE_ID == 0x300
    assert cls.BROADCAST_PERIOD == 0.1
    params = {p.key: p for p in cls.PARAMS}
    assert params['current_sensor'].default == ''
    bank = params['bank_count']
    assert (bank.default, bank.low, bank.high, bank.read_only) == (1, 1, 5, False)


@pytest.mark.parametrize('bad', [0, 6, 2.5, 'x'])
def test_bad_bank_count_refused(clock, bad):
    with pytest.raises(ValueError, match='ams.bank_count .* allowed 1..5'):
        make(clock, bank_count=bad)


def test_nothing_received(clock):
    device = make(clock)
    report = device.battery_report()
    assert not report.present
    assert math.isnan(report.voltage) and math.isnan(report.current)
    assert math.isnan(report.percentage) and math.isnan(report.temperature)
    assert report.power_supply_health == PowerSupplyHealth.UNKNOWN
    assert len(report.cell_voltage) == 28 and all(math.isnan(v) for v in report.cell_voltage)
    assert device.diagnostic_report().level == Level.STALE
    assert device.state is AmsState.NOT_REPORTED and device.status_seq == 0
    arrays = device.extra_arrays()
    assert arrays['temperatures'][:2] == (1, 10)
    assert arrays['discharge_temperatures'][:2] == (1, 14)
    assert all(math.isnan(v) for v in arrays['temperatures'][2])


def test_status_only(clock):
    device = make(clock)
    assert status(device, relay_error=0x05) is True  # the primary frame
    report = device.battery_report()
    assert report.present and report.stamp == STAMP
    assert report.percentage == pytest.approx(0.77)
    assert report.temperature == 35.0  # Temp_max: no cell temperature received yet
    assert math.isnan(report.voltage)  # cells missing, no IVT-S
    assert math.isnan(report.current) and math.isnan(report.charge)
    assert report.power_supply_status == PowerSupplyStatus.UNKNOWN
    assert report.power_supply_health == PowerSupplyHealth.GOOD
    diag = device.diagnostic_report()
    assert diag.level == Level.OK
    assert diag.message == 'DRIVE; AIR+ closed, AIR- closed, precharge open'
    v = diag.values
    assert (v['state'], v['air_plus'], v['air_minus'], v['precharge']) == (
        'DRIVE', 'true', 'true', 'false')
    assert (v['volt_min (V)'], v['temp_max (degC)'], v['SOC (%)'], v['counter']) == (
        '3.60', '35', '77', '0')
    assert (v['relay error AIR-'], v['relay error AIR+'], v['relay error precharge']) == (
        'true', 'false', 'true')
    assert v['cells received'] == '0/28'
    assert device.state is AmsState.DRIVE and device.status_seq == 1


def test_cells_fill_in_order_and_sum_once_complete(clock):
    device = make(clock)
    status(device)
    cells(device, 1, 2, raw=(150, 151, 152, 153, 154, 155, 156))  # cells 15..21
    report = device.battery_report()
    assert report.cell_voltage[14:21] == pytest.approx([3.0, 3.02, 3.04, 3.06, 3.08, 3.1, 3.12])
    assert math.isnan(report.cell_voltage[13]) and math.isnan(report.cell_voltage[21])
    assert math.isnan(report.voltage)  # not all 28 cells yet
    for group in (0, 1, 3):
        cells(device, 1, group)
    report = device.battery_report()
    assert report.voltage == pytest.approx(21 * 3.6 + sum(range(150, 157)) * 0.02)
    diag = device.diagnostic_report()
    assert diag.values['cells received'] == '28/28'
    assert diag.values['cell min (V)'] == '3.00' and diag.values['cell max (V)'] == '3.60'


def test_two_banks(clock):
    device = make(clock, bank_count=2)
    status(device, banks=2)
    cells(device, 2, 3, raw=(200,) * 7)
    report = device.battery_report()
    assert len(report.cell_voltage) == 56
    assert report.cell_voltage[49:56] == pytest.approx([4.0] * 7)
    temps(device, 2, 1, (10, 11, 12, 13, 14))
    data = device.extra_arrays()['temperatures']
    assert data[:2] == (2, 10)
    assert data[2][15:20] == [10.0, 11.0, 12.0, 13.0, 14.0]
    assert all(math.isnan(t) for t in data[2][:15])
    assert device.diagnostic_report().level == Level.OK


def test_hottest_cell_is_the_temperature(clock):
    device = make(clock)
    status(device, temp_max=35)
    temps(device, 1, 0, (20, -5, 41, 22, 23))
    temps(device, 1, 1, (-40, 0, 0, 0, 0))
    assert device.battery_report().temperature == 41.0
    discharge(device, 1, 1, (1, 2, 3, 4, 5, 6, -7))
    data = device.extra_arrays()['discharge_temperatures'][2]
    assert data[7:] == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, -7.0]
    assert all(math.isnan(t) for t in data[:7])


def test_banks_beyond_bank_count_warn(clock):
    device = make(clock)
    status(device)
    cells(device, 3, 0)
    temps(device, 3, 1)
    report = device.battery_report()
    assert len(report.cell_voltage) == 28  # bank 3 is not shown
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert '2 frames from bank(s) up to 3 beyond ams.bank_count = 1' in diag.message
    assert 'set ams.bank_count to 3' in diag.message
    assert device.frames_malformed == 0
    # the node changes the parameter at run time: bank 3 becomes visible
    device.configure({'bank_count': 3})
    assert device.battery_report().cell_voltage[56:63] == pytest.approx([3.6] * 7)


def test_messages_name_the_instance_not_the_type(clock):
    device = AmsDevice('front', {'bank_count': 1}, clock=clock)
    status(device)
    cells(device, 3, 0)
    message = device.diagnostic_report().message
    assert 'beyond front.bank_count = 1' in message and 'set front.bank_count to 3' in message
    assert 'ams.' not in message
    with pytest.raises(ValueError, match=r'^front\.bank_count = 9: allowed 1\.\.5'):
        AmsDevice('front', {'bank_count': 9}, clock=clock)


def test_ams_bank_count_mismatch_warns(clock):
    device = make(clock, bank_count=2)
    status(device, banks=1)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'AMS reports 1 bank(s), ams.bank_count = 2' in \
        diag.message


@pytest.mark.parametrize('code,health', [
    (AmsError.CELL_VOLTAGE_HIGH, PowerSupplyHealth.OVERVOLTAGE),
    (AmsError.CELL_VOLTAGE_LOW, PowerSupplyHealth.DEAD),
    (AmsError.CELL_TEMP_HIGH, PowerSupplyHealth.OVERHEAT),
    (AmsError.CELL_TEMP_LOW, PowerSupplyHealth.COLD),
    (AmsError.SC_BROKEN, PowerSupplyHealth.UNSPEC_FAILURE),
    (AmsError.UNABLE_TO_CLOSE_AIR_PLUS, PowerSupplyHealth.UNSPEC_FAILURE),
])
def test_error_event_health(clock, code, health):
    device = make(clock)
    status(device)
    assert error(device, code, tick=0xABCD) is False
    assert device.battery_report().power_supply_health == health
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert f'errors: {code.name}' in diag.message
    assert diag.values['last error'] == f'{code.name} at tick {0xABCD}'
    assert device.last_error is code and device.error_seq == 1


def test_error_stays_active_until_the_ams_leaves_its_error_state(clock):
    device = make(clock)
    status(device, counter=0)
    error(device, AmsError.CELL_TEMP_HIGH)
    status(device, state=AmsState.ERROR, flags=0x01, counter=1)
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert diag.message.startswith('ERROR; ')
    assert 'AMS in ERROR' in diag.message and 'AMS error bit set' in diag.message
    assert device.master_view().errors == 'CELL_TEMP_HIGH'
    status(device, state=AmsState.IDLE, flags=0x00, counter=2)
    assert device.diagnostic_report().level == Level.OK
    assert device.battery_report().power_supply_health == PowerSupplyHealth.GOOD
    assert device.last_error is AmsError.CELL_TEMP_HIGH  # history stays readable
    assert device.active_errors() == []


@pytest.mark.parametrize('state,flags,text', [
    (AmsState.ERROR, 0x00, 'AMS in ERROR'),
    (AmsState.CHARGE_ERROR, 0x00, 'AMS in CHARGE_ERROR'),
    (AmsState.IDLE, 0x02, 'IMD error'),
    (AmsState.IDLE, 0x01, 'AMS error bit set'),
])
def test_error_states_and_bits(clock, state, flags, text):
    device = make(clock)
    status(device, state=state, flags=flags)
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR and text in diag.message
    assert device.battery_report().power_supply_health == PowerSupplyHealth.UNSPEC_FAILURE


@pytest.mark.parametrize('flags,text', [(0x10, 'cell voltage close to its limits'),
                                        (0x08, 'cell temperature close to its limits')])
def test_warning_bits(clock, flags, text):
    device = make(clock)
    status(device, state=AmsState.IDLE, flags=flags)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and text in diag.message
    assert device.battery_report().power_supply_health == PowerSupplyHealth.GOOD


def test_counter_stuck_warns_then_recovers(clock):
    device = make(clock)
    for _ in range(3):
        status(device, counter=9)
        clock.now += 0.1
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'status counter stuck at 9 (2 repeated frames)' in diag.message
    assert diag.values['counter repeats'] == '2'
    for counter in range(10, 21):
        status(device, counter=counter)
        clock.now += 0.1
    assert device.diagnostic_report().level == Level.OK


def test_counter_jump_counts_lost_frames(clock):
    device = make(clock)
    status(device, counter=250)
    status(device, counter=251)
    status(device, counter=3)  # 252..255, 0..2 lost: 7 frames, across the wrap
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert 'status counter jumped: 7 frames lost so far' in diag.message
    assert diag.values['frames lost (counter jumps)'] == '7'
    for counter in range(4, 14):
        status(device, counter=counter)
    assert device.diagnostic_report().level == Level.OK


def test_counter_wrap_is_fine(clock):
    device = make(clock)
    for counter in (254, 255, 0, 1):
        status(device, counter=counter)
    diag = device.diagnostic_report()
    assert diag.level == Level.OK and diag.values['frames lost (counter jumps)'] == '0'


def test_stale(clock):
    device = make(clock)
    status(device)
    for group in range(4):
        cells(device, 1, group)
    clock.now += 0.4
    assert device.battery_report().present
    clock.now += 0.2  # 0.6 s > stale_timeout 0.5 s
    report = device.battery_report()
    assert not report.present
    # silent status frame: no measurement at all, even from recent cells (no flat line
    # in a plot that looks alive); the last real values were in the last present message
    assert math.isnan(report.voltage) and all(math.isnan(v) for v in report.cell_voltage)
    diag = device.diagnostic_report()
    assert diag.level == Level.STALE and 'silent for 0.6 s' in diag.message
    # a restart after the silence: the new counter is no jump
    status(device, counter=77)
    assert device.diagnostic_report().level == Level.OK
    clock.now += 5.1  # cells are sent every 1 s: after 5 s without them they are unknown
    status(device, counter=78)
    report = device.battery_report()
    assert report.present and math.isnan(report.voltage)
    assert all(math.isnan(v) for v in report.cell_voltage)


def test_charging_state(clock):
    device = make(clock)
    status(device, state=AmsState.CHARGING, flags=0xC0)
    assert device.battery_report().power_supply_status == PowerSupplyStatus.CHARGING


def test_soc_out_of_range(clock):
    device = make(clock)
    status(device, soc=200)
    assert math.isnan(device.battery_report().percentage)
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'SOC 200 % out of range' in diag.message


def test_malformed_frames_counted_not_applied(clock):
    device = make(clock)
    status(device, soc=50)
    assert device.handle_frame(0x300, bytes(6), STAMP) is False  # wrong DLC
    assert device.handle_frame(0x311, bytes([0xE0]) + bytes(7), STAMP) is False  # bank 7
    assert device.handle_frame(0x314, bytes([0, 0, 0]), STAMP) is False  # error ID 0
    assert device.frames_malformed == 3
    values = device.diagnostic_report().values
    assert values['frames malformed'] == '3'
    assert values['last malformed frame'].endswith('unknown AMS error ID 0 (known 1..23)')
    assert device.battery_report().percentage == pytest.approx(0.5)
    assert device.error_seq == 0


def test_master_view_and_other_frames(clock):
    device = make(clock)
    view = device.master_view()
    assert view.status_seq == 0 and view.stale
    status(device, state=AmsState.SC_ENABLED)
    device.handle_frame(0x305, bytes([0x11, 0x07]), STAMP)  # a master's ENABLE_SC
    device.handle_frame(0x301, bytes([0x20, 0x27, 0x32, 0x7B, 0x01]), STAMP)
    device.handle_frame(0x310, bytes([0x01, 0x00, 0x10]), STAMP)
    view = device.master_view()
    assert (view.state, view.status_seq, view.error_seq, view.stale) == (
        AmsState.SC_ENABLED, 1, 0, False)
    v = device.diagnostic_report().values
    assert v['car status: command'] == 'ENABLE_SC' and v['car status: counter'] == '7'
    assert v['charger status: current (A)'] == '12.3'
    assert v['charger command'] == 'START at tick 16'


def test_charger_status_car_status_and_charger_command_expire_on_their_own(clock):
    device = make(clock)
    status(device)
    device.handle_frame(0x305, bytes([0x11, 0x07]), STAMP)
    device.handle_frame(0x301, bytes([0x20, 0x27, 0x32, 0x7B, 0x01]), STAMP)
    device.handle_frame(0x310, bytes([0x01, 0x00, 0x10]), STAMP)
    clock.now += 0.4
    status(device, counter=1)
    device.handle_frame(0x305, bytes([0x11, 0x08]), STAMP)  # only the car status goes on
    v = device.diagnostic_report().values
    assert v['charger status: SOC (%)'] == '50' and v['charger command'] == 'START at tick 16'
    clock.now += 0.2  # 0.6 s after the charger frames (stale_timeout 0.5 s), 0.2 s after the rest
    status(device, counter=2)
    v = device.diagnostic_report().values
    assert 'charger status: SOC (%)' not in v and 'charger command' not in v
    assert v['car status: counter'] == '8'
    assert device.diagnostic_report().level != Level.STALE


def test_non_default_base(clock):
    device = make(clock, base_id=0x400)
    assert 0x400 in device.arbitration_ids and 0x300 not in device.arbitration_ids
    assert status(device, base=0x400) is True
    assert device.state is AmsState.DRIVE


def ivt_frame(ivt, kind, value, counter=0):
    """IVT-S result: b0 mux ID, b1 counter, b2..5 signed BE (mA / mV / As)."""
    scale = 1000 if kind in (0, 1, 2, 3) else 1  # mA, mV; As as is
    data = bytes([kind, counter]) + round(value * scale).to_bytes(4, 'big', signed=True)
    ivt.handle_frame(0x521 + kind, data, STAMP)


def test_pack_values_from_the_real_ivt_s(clock):
    ivt = IvtSDevice('ivt_s', {}, clock=clock)
    device = make(clock)
    device.attach_current_sensor(ivt)
    status(device)
    for group in range(4):
        cells(device, 1, group)  # cell sum 100.8 V must NOT be used when an IVT-S is there
    report = device.battery_report()
    assert math.isnan(report.voltage) and math.isnan(report.current)
    assert report.power_supply_status == PowerSupplyStatus.UNKNOWN
    ivt_frame(ivt, 0, 120.5)  # I: wire positive = discharge (IVT-S default mounting)
    ivt_frame(ivt, 1, 98.7)  # U1
    ivt_frame(ivt, 6, 3600)  # As counter: 1 Ah since the sensor's reset, not the charge
    report = device.battery_report()
    assert report.current == pytest.approx(-120.5)
    assert report.voltage == pytest.approx(98.7)
    assert math.isnan(report.charge) and math.isnan(report.design_capacity)
    assert report.power_supply_status == PowerSupplyStatus.DISCHARGING
    ivt_frame(ivt, 0, -20.0)
    assert device.battery_report().power_supply_status == PowerSupplyStatus.CHARGING
    assert device.diagnostic_report().values['current sensor'] == 'ivt_s'
    clock.now += 0.4
    status(device, counter=1)
    clock.now += 0.2  # the IVT-S went silent, the AMS did not
    report = device.battery_report()
    assert report.present and math.isnan(report.current) and math.isnan(report.voltage)


def test_override_frames_are_not_consumed_so_sma_0x351_can_share_the_bus():
    device = AmsDevice('ams', {})
    assert 0x351 not in device.arbitration_ids and 0x350 not in device.arbitration_ids
    assert {0x300, 0x301, 0x311, 0x312, 0x313, 0x314} <= device.arbitration_ids


def test_the_device_builds_its_command_frames_at_its_base_id(clock):
    device = make(clock, base_id=0x400, bank_count=3)
    assert device.heartbeat_frame(2, 3, 7) == Frame(0x405, bytes([0x32, 7]))
    assert device.charger_frame(ChargerStart.START, 0x1234) == Frame(0x410, b'\x01\x12\x34')
    assert device.bank_count_frame() == Frame(0x451, bytes([3]))
    with pytest.raises(RefusedCommand, match=r'^ams\.charge_current_a is not set'):
        device.charge_current_frame()
    device.configure({'charge_current_a': 12.3})
    assert device.charge_current_frame() == Frame(0x450, bytes([123]))


def test_a_padding_ams_is_decoded_and_never_stale(clock):
    """Frames padded to 8 bytes (doc/protocols.md section 1, DLC) count as received."""
    device = make(clock)
    for counter in range(12):  # 1.2 s of status every 100 ms, each padded with 0xFF
        clock.now += 0.1
        data = bytes([0xC0, 1 << 5 | AmsState.DRIVE, 180, 35, 77, counter, 0, 0xFF])
        assert device.handle_frame(0x300, data, STAMP) is True
        assert not device.is_stale()
    # cells and temperatures padded too (0x012 has a 6-byte layout)
    device.handle_frame(0x312, bytes([0x20, 20, 21, 22, 23, 24, 0, 0]), STAMP)
    assert device.frames_malformed == 0
    assert device.battery_report().present
    assert device.extra_arrays()['temperatures'][2][:5] == [20.0, 21.0, 22.0, 23.0, 24.0]
    # one byte short of the layout is malformed and keeps nothing
    assert device.handle_frame(0x300, bytes([0xC0, 0x24, 180, 35, 77, 12]), STAMP) is False
    assert device.frames_malformed == 1


def test_charge_is_design_capacity_times_soc_never_the_ivt_s_counter(clock):
    """BatteryState.charge = remaining Ah: design_capacity_ah x SOC, NaN while unset."""
    ivt = IvtSDevice('ivt_s', {}, clock=clock)
    device = make(clock)
    device.attach_current_sensor(ivt)
    ivt_frame(ivt, 6, -7200)  # As counter after a drive: -2 Ah, meaningless as a charge
    status(device, soc=77)
    report = device.battery_report()
    assert math.isnan(report.charge) and math.isnan(report.design_capacity)
    assert device.diagnostic_report().values['design capacity (Ah)'] == 'unset'
    device = make(clock, design_capacity_ah=20)  # YAML may spell it as an int
    device.attach_current_sensor(ivt)
    status(device, soc=77)
    report = device.battery_report()
    assert report.design_capacity == pytest.approx(20.0)
    assert report.charge == pytest.approx(15.4)  # 20 Ah x 77 %
    assert math.isnan(report.capacity)  # the last full capacity is not measured
    assert device.diagnostic_report().values['design capacity (Ah)'] == '20'
    status(device, soc=101, counter=1)  # SOC out of range: unknown, and so the charge
    report = device.battery_report()
    assert math.isnan(report.percentage) and math.isnan(report.charge)


@pytest.mark.parametrize('channel,kind', [('U1', 1), ('U2', 2), ('U3', 3)])
def test_pack_voltage_from_the_chosen_ivt_s_channel(clock, channel, kind):
    ivt = IvtSDevice('ivt_s', {}, clock=clock)
    params = {} if channel == 'U1' else {'pack_voltage_channel': channel}  # U1 by default
    device = make(clock, **params)
    device.attach_current_sensor(ivt)
    status(device)
    for k, volts in ((1, 101.1), (2, 202.2), (3, 303.3)):  # a different value on each
        ivt_frame(ivt, k, volts)
    assert device.battery_report().voltage == pytest.approx(101.1 * kind)
    assert device.diagnostic_report().values['pack voltage channel'] == channel


def test_pack_voltage_channel_is_one_of_u1_u2_u3():
    spec = next(p for p in AmsDevice.PARAMS if p.key == 'pack_voltage_channel')
    assert (spec.default, spec.choices) == ('U1', ('U1', 'U2', 'U3'))
