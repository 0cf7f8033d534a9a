# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge node in-process on python-can 'virtual': golden frames in, exact messages out.

Frames are written by hand from doc/protocols.md (not through the codecs or the DBC); a real
subscriber node receives what the bridge publishes (``rig_factory``, conftest.py).
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import time

import pytest
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray

from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.ros.bridge_node import BridgeNode, ConfigError
from command_rig import Rig
from helpers import ros_context, wait_for
from shared import bms16_status, level, values

NAN = math.nan
_ids = itertools.count()


@pytest.fixture(scope='module')
def context():
    with ros_context() as ctx:
        yield ctx


def approx_list(expected: list[float]):
    return [pytest.approx(v, rel=1e-6, nan_ok=True) for v in expected]


# --- CAN bus diagnostics ------------------------------------------------------------------
def test_can_bus_status_without_devices(rig_factory):
    h = rig_factory({'diagnostics_period': 0.2})
    status = h.status('CAN bus', lambda s: values(s).get('state') == 'connected')
    assert level(status) == 0
    assert status.hardware_id == f'virtual:{h.channel}'
    v = values(status)
    for key in ('state', 'reason', 'frames in', 'frames out', 'malformed frames',
                'error frames', 'reconnects', 'replay'):
        assert key in v
    assert v['replay'] == 'off'
    assert v['frames out'] == '0'


# --- parameters ---------------------------------------------------------------------------
def test_numeric_parameters_accept_int_and_float_spellings(rig_factory):
    h = rig_factory({'diagnostics_period': 1, 'can.reconnect_period': 2,
                     'devices': ['ivt_s'], 'ivt_s.stale_timeout': 3, 'can.bitrate': 500000.0,
                     'commands_allowed': True})
    node = h.node
    assert node.diagnostics_period == 1.0
    assert node.bus_config.reconnect_period == 2.0
    assert node.bus_config.bitrate == 500000 and isinstance(node.bus_config.bitrate, int)
    assert node.devices['ivt_s'].stale_timeout == 3.0
    # a later set with either spelling works too, and a bad one is refused with a reason
    ok = node.set_parameters([Parameter('commands_enabled', value=True)])[0]
    assert ok.successful and node.commands_enabled
    bad = node.set_parameters([Parameter('commands_enabled', value=3)])[0]
    assert not bad.successful


def test_read_only_and_commands_enabled_gate(rig_factory):
    h = rig_factory({'devices': ['bms16'], 'commands_allowed': True})
    node = h.node
    refused = node.set_parameters([Parameter('can.channel', value='x')])[0]
    assert not refused.successful
    ok, message = node.gate.transmit(Frame(506, b''))
    assert not ok and 'commands_enabled' in message
    assert node.can_io.status().frames_out == 0
    assert node.set_parameters([Parameter('commands_enabled', value=True)])[0].successful
    ok, message = node.gate.transmit(Frame(506, b''))
    assert ok, message
    assert node.can_io.status().frames_out == 1


@pytest.mark.parametrize('params, words', [
    ({'devices': ['pack'], 'pack.type': 'zeva'}, ['pack.type', 'bms16']),
    ({'devices': ['nosuch']}, ['nosuch.type', 'ams']),
    ({'devices': ['ivt_s'], 'ivt_s.byte_order': 'middle'}, ['ivt_s.byte_order', 'big']),
    ({'devices': ['ivt_s'], 'ivt_s.stale_timeout': -1.0}, ['ivt_s.stale_timeout', '3600']),
    ({'can.options': ['novalue']}, ['can.options', 'key=value']),
    ({'diagnostics_period': 'fast'}, ['diagnostics_period', 'number']),
])
def test_bad_parameters_name_what_to_change(context, params, words):
    overrides = {'can.interface': 'virtual', 'can.channel': f'bad-{next(_ids)}'}
    overrides.update(params)
    with pytest.raises(ConfigError) as info:
        BridgeNode(context=context, namespace=f'bad_{next(_ids)}',
                   parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
    for word in words:
        assert word in str(info.value)


# --- IVT-S -------------------------------------------------------------------------------
def ivt(mux: int, counter: int, value: int) -> bytes:
    """IVT-S result frame: b0 mux, b1 counter (bits 3..0), b2..5 int32 big-endian."""
    return bytes([mux, counter & 0x0F]) + value.to_bytes(4, 'big', signed=True)


def test_ivt_s_battery_state_sign_and_diagnostics(rig_factory):
    h = rig_factory({'devices': ['shunt'], 'shunt.type': 'ivt_s', 'shunt.frame_id': 'pack',
                     'diagnostics_period': 0.2},
                    topics={'shunt/battery_state': BatteryState})
    h.send(0x522, ivt(1, 0, 403_500))  # U1 403.5 V
    h.send(0x527, ivt(6, 0, -36_000))  # -36000 As = 10 Ah discharged (wire: + = discharge)
    h.send(0x521, ivt(0, 0, 25_000))  # +25 A on the wire = discharging
    msg = h.last('shunt/battery_state', lambda m: m.present and m.voltage == m.voltage)
    assert msg.header.frame_id == 'pack'
    assert msg.current == pytest.approx(-25.0)
    assert msg.voltage == pytest.approx(403.5)
    assert math.isnan(msg.charge)  # the As counter is not the charge in the battery (#17)
    assert msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    assert math.isnan(msg.percentage) and math.isnan(msg.temperature)
    assert abs(msg.header.stamp.sec - time.time()) < 60
    status = h.status('shunt', lambda s: level(s) != 3)
    assert status.hardware_id == f'virtual:{h.channel}'
    assert '-25.00 A' in status.message
    assert values(status)['I raw (mA)'] == '25000'


# --- BMS16 -------------------------------------------------------------------------------
def bms16_cells(centivolts: list[int]) -> bytes:
    """ID 501..503: low 8 bits of each cell, then b6 bit n = 9th bit of cell n."""
    high = sum(((v >> 8) & 1) << n for n, v in enumerate(centivolts))
    return bytes(v & 0xFF for v in centivolts) + bytes(6 - len(centivolts)) + bytes([high])


def test_bms16_battery_state_and_cells(rig_factory):
    h = rig_factory({'devices': ['bms16'], 'diagnostics_period': 0.2},
                    topics={'bms16/battery_state': BatteryState})
    h.send(501, bms16_cells([330, 331, 250, 255, 256, 420]))
    h.send(500, bms16_status(0, 80, 523, 125, 25))  # 12.5 A discharging
    msg = h.last('bms16/battery_state', lambda m: m.present)
    assert msg.voltage == pytest.approx(52.3)
    assert msg.current == pytest.approx(-12.5)
    assert msg.percentage == pytest.approx(0.8)
    assert msg.temperature == pytest.approx(25.0)
    assert msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    assert msg.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_GOOD
    assert len(msg.cell_voltage) == 16
    assert list(msg.cell_voltage) == approx_list([3.30, 3.31, 2.50, 2.55, 2.56, 4.20]
                                                 + [NAN] * 10)
    status = h.status('bms16', lambda s: level(s) == 0)
    assert 'SoC 80 %' in status.message
    assert values(status)['cell 1 V'] == '3.3'
    # an overvoltage error (3) -> ERROR level, health OVERVOLTAGE, published at once
    h.send(500, bms16_status(3, 80, 523, -40, 25))  # 4.0 A charging
    msg = h.last('bms16/battery_state', lambda m: m.power_supply_health == 4)
    assert msg.current == pytest.approx(4.0)
    assert msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_CHARGING
    status = h.status('bms16', lambda s: level(s) == 2)
    assert 'CHARGE_DISABLED_OVERVOLTAGE' in status.message


# --- AMS (+ IVT-S) -----------------------------------------------------------------------
def ams_status(word: int, volt_min: int, temp_max: int, soc: int, counter: int) -> bytes:
    """0x300: b0..1 status word BE, b2 Volt_min 20 mV, b3 Temp_max, b4 SOC, b5 counter, b6."""
    return word.to_bytes(2, 'big') + bytes([volt_min, temp_max, soc, counter, 0])


def bank_group(bank: int, group: int) -> int:
    return (bank << 5) | group


def int8s(values: list[int]) -> bytes:
    return bytes(v & 0xFF for v in values)


AIR_PLUS, AIR_MINUS, DRIVE = 1 << 15, 1 << 14, 4


def send_ams_bank(h: Rig) -> None:
    for group in range(4):  # 28 cells: 3.60 V + 20 mV * (group)
        h.send(0x311, [bank_group(1, group)] + [180 + group] * 7)
    h.send(0x312, [bank_group(1, 0)] + [20, 21, 22, 23, 24])
    h.send(0x312, [bank_group(1, 1)] + list(int8s([25, 26, 27, 28, -5])))
    h.send(0x313, [bank_group(1, 0)] + [30, 31, 32, 33, 34, 35, 36])


def test_ams_without_current_sensor(rig_factory):
    h = rig_factory({'devices': ['ams'], 'diagnostics_period': 0.2},
                    topics={'ams/battery_state': BatteryState,
                            'ams/temperatures': Float32MultiArray,
                            'ams/discharge_temperatures': Float32MultiArray})
    send_ams_bank(h)
    h.send(0x300, ams_status(AIR_PLUS | AIR_MINUS | (1 << 5) | DRIVE, 180, 28, 77, 1))
    msg = h.last('ams/battery_state', lambda m: m.present)
    cells = [3.60] * 7 + [3.62] * 7 + [3.64] * 7 + [3.66] * 7
    assert list(msg.cell_voltage) == approx_list(cells)
    assert msg.voltage == pytest.approx(sum(cells), rel=1e-5)
    assert math.isnan(msg.current) and math.isnan(msg.charge)
    assert msg.percentage == pytest.approx(0.77)
    assert msg.temperature == pytest.approx(28.0)
    assert msg.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_GOOD
    temps = h.last('ams/temperatures')
    assert [d.size for d in temps.layout.dim] == [1, 10]
    assert list(temps.data) == approx_list([20, 21, 22, 23, 24, 25, 26, 27, 28, -5])
    discharge = h.last('ams/discharge_temperatures')
    assert [d.size for d in discharge.layout.dim] == [1, 14]
    assert list(discharge.data) == approx_list([30, 31, 32, 33, 34, 35, 36] + [NAN] * 7)
    status = h.status('ams', lambda s: level(s) == 0)
    assert 'DRIVE' in status.message and 'AIR+ closed' in status.message
    assert values(status)['state'] == 'DRIVE'


def test_ams_with_ivt_s_current_sensor(rig_factory):
    h = rig_factory({'devices': ['ams', 'shunt'], 'shunt.type': 'ivt_s',
                     'diagnostics_period': 0.2, 'ams.pack_voltage_channel': 'U2',
                     'ams.design_capacity_ah': 20.0},
                    topics={'ams/battery_state': BatteryState,
                            'shunt/battery_state': BatteryState})
    # the link is resolved, never written behind the parameter server (issue 21.5)
    assert h.node.devices['ams'].current_sensor is h.node.devices['shunt']
    assert h.node.devices['ams'].config.current_sensor == ''
    assert h.node.get_parameter('ams.current_sensor').value == ''
    h.send(0x522, ivt(1, 0, 12_000))  # U1 12 V: not the pack here
    h.send(0x523, ivt(2, 0, 398_000))  # U2 398 V: ams.pack_voltage_channel
    h.send(0x527, ivt(6, 0, 7200))  # As counter: never the charge
    h.send(0x521, ivt(0, 0, -30_000))  # -30 A on the wire (discharge positive) = charging
    h.last('shunt/battery_state', lambda m: m.present)
    h.send(0x300, ams_status(AIR_PLUS | AIR_MINUS | (1 << 5) | 8, 180, 30, 50, 7))
    msg = h.last('ams/battery_state', lambda m: m.present)
    assert msg.voltage == pytest.approx(398.0)
    assert msg.current == pytest.approx(30.0)
    assert msg.charge == pytest.approx(10.0)  # 20 Ah x SOC 50 %
    assert msg.design_capacity == pytest.approx(20.0)
    assert msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_CHARGING
    assert len(msg.cell_voltage) == 28 and all(math.isnan(v) for v in msg.cell_voltage)


def test_ams_current_sensor_must_be_an_ivt_s(context):
    with pytest.raises(ConfigError) as info:
        BridgeNode(context=context, namespace=f'bad_{next(_ids)}', parameter_overrides=[
            Parameter('can.interface', value='virtual'),
            Parameter('can.channel', value=f'bad-{next(_ids)}'),
            Parameter('devices', value=['ams', 'bms16']),
            Parameter('ams.current_sensor', value='bms16')])
    assert 'ams.current_sensor' in str(info.value) and 'ivt_s' in str(info.value)


# --- SMA ---------------------------------------------------------------------------------
def le16(value: int) -> bytes:
    return (value & 0xFFFF).to_bytes(2, 'little')


def test_sma_battery_state(rig_factory):
    h = rig_factory({'devices': ['sma'], 'diagnostics_period': 0.2},
                    topics={'sma/battery_state': BatteryState})
    h.send(0x351, le16(552) + le16(500) + le16(1000) + le16(480))  # 55.2 / 48 V: 0.01 V
    h.send(0x355, le16(64) + le16(98))  # SoC 64 %, SoH 98 %
    h.send(0x35A, bytes([0xAA] * 4 + [0xAA] * 4))  # every condition OK
    h.send(0x356, le16(5120) + le16(-153) + le16(231))  # 51.2 V, -15.3 A, 23.1 degC
    msg = h.last('sma/battery_state', lambda m: m.present)
    assert msg.voltage == pytest.approx(51.2)
    assert msg.current == pytest.approx(-15.3)
    assert msg.temperature == pytest.approx(23.1)
    assert msg.percentage == pytest.approx(0.64)
    assert msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    assert msg.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_GOOD
    assert math.isnan(msg.charge)  # capacity (0x35F) not received
    status = h.status('sma', lambda s: level(s) == 0)
    assert 'SoC 64' in status.message


# --- EVMS3 (+ BMS12 modules) ----------------------------------------------------------------
def be16(*values: int) -> bytes:
    return b''.join(v.to_bytes(2, 'big') for v in values)


def test_evms3_battery_state_with_bms12_cells(rig_factory):
    h = rig_factory({'devices': ['evms3'], 'evms3.bms12_modules': 1,
                     'evms3.config.pack_capacity_ah': 200, 'diagnostics_period': 0.2},
                    topics={'evms3/battery_state': BatteryState})
    h.send(301, be16(3300, 3310, 3320, 3330), extended=True)  # BMS12 module 0, cells 1-4
    h.send(302, be16(3340, 3350, 3360, 3370), extended=True)
    h.send(303, be16(3380, 3390, 3400, 3410), extended=True)
    h.send(40, (8_388_608 + 20_000).to_bytes(3, 'big'), extended=True)  # 20 A discharge
    # ID 30: Running, 123.4 Ah, 345.6 V, aux 13.1 V, isolation 99 %, 25 degC
    h.send(30, bytes([0x02, 0x04, 0xD2, 0x0D, 0x80, 131, 99, 65]), extended=True)
    msg = h.last('evms3/battery_state', lambda m: m.present and len(m.cell_voltage) == 12
                 and m.cell_voltage[11] == m.cell_voltage[11])
    assert msg.voltage == pytest.approx(345.6)
    assert msg.charge == pytest.approx(123.4)
    assert msg.capacity == pytest.approx(200.0)
    assert msg.percentage == pytest.approx(0.617)
    assert msg.current == pytest.approx(-20.0)
    assert msg.temperature == pytest.approx(25.0)
    assert list(msg.cell_voltage) == approx_list([3.30 + 0.01 * k for k in range(12)])
    assert msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    status = h.status('evms3', lambda s: level(s) == 0)
    assert status.hardware_id == f'virtual:{h.channel}'


def test_device_parameters_are_checked_and_applied_by_the_device(rig_factory):
    h = rig_factory({'devices': ['evms3']})
    node = h.node
    device = node.devices['evms3']
    assert 'evms3' in node.command_services
    before = device.config
    # within the declared ROS range (any int[]), refused by the device: 16 values needed
    refused = node.set_parameters([Parameter('evms3.config.cells_per_module', value=[12])])[0]
    assert not refused.successful
    assert refused.reason.startswith('evms3.config.cells_per_module = (12,) refused: allowed 16')
    assert device.config is before  # a refused set leaves the configuration untouched
    accepted = node.set_parameters_atomically([
        Parameter('evms3.config.pack_capacity_ah', value=100),
        Parameter('evms3.config.balance_mode', value='dynamic')])
    assert accepted.successful, accepted.reason
    # one atomic set = one new frozen configuration with both values
    assert (device.config.config_pack_capacity_ah, device.config.config_balance_mode) == \
        (100, 'dynamic')
    assert before.config_pack_capacity_ah is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        device.config.config_pack_capacity_ah = 1


# --- header, stamps, diagnostics on change -------------------------------------------------
def stamp_seconds(msg: BatteryState) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_location_serial_number_and_frame_id_parameters_reach_battery_state(rig_factory):
    h = rig_factory({'devices': ['bms16'], 'bms16.location': 'rear rack, slot 2',
                     'bms16.serial_number': 'SN-0042', 'bms16.frame_id': 'battery_link'},
                    topics={'bms16/battery_state': BatteryState})
    h.send(500, bms16_status(0, 70, 520, 10, 24))
    msg = h.last('bms16/battery_state', lambda m: m.present)
    assert msg.location == 'rear rack, slot 2'
    assert msg.serial_number == 'SN-0042'
    assert msg.header.frame_id == 'battery_link'


def test_stamp_is_the_receive_time_and_stale_messages_the_publish_time(rig_factory):
    # spin=False: the executor runs only while the test waits, so publishing can be held back
    h = rig_factory({'devices': ['bms16'], 'bms16.stale_timeout': 0.8},
                    topics={'bms16/battery_state': BatteryState}, spin=False)
    # Before any frame the 1 Hz stale message has no receive time: it is stamped 'now'.
    created = time.time()
    never = h.last('bms16/battery_state', lambda m: not m.present)
    assert created - 0.05 <= stamp_seconds(never) <= time.time()

    def send_soc(soc: int) -> tuple[float, float, BatteryState]:
        before = time.time()
        h.send(500, bms16_status(0, soc, 520, 10, 24))
        msg = h.last('bms16/battery_state',
                     lambda m: m.present and m.percentage == pytest.approx(soc / 100))
        return before, time.time(), msg

    before1, after1, first = send_soc(61)
    assert before1 - 0.05 <= stamp_seconds(first) <= after1
    h.wait(lambda: time.time() >= after1 + 0.3, timeout=5.0)
    before2, after2, second = send_soc(62)
    assert before2 - 0.05 <= stamp_seconds(second) <= after2
    gap = stamp_seconds(second) - stamp_seconds(first)
    assert 0.15 <= gap <= after2 - before1 + 0.05, gap
    # Published later than received (executor held back): still the receive time.
    frames_in = h.node.can_io.status().frames_in
    h.send(500, bms16_status(0, 63, 520, 10, 24))
    wait_for(lambda: h.node.can_io.status().frames_in > frames_in, what='frame received')
    received_by = time.time()
    time.sleep(0.3)  # the executor does not spin: publishing waits
    third = h.last('bms16/battery_state',
                   lambda m: m.present and m.percentage == pytest.approx(0.63))
    assert stamp_seconds(third) <= received_by
    # Once stale, present:false is stamped when it is published (issue 18.7), so it never
    # repeats the last frame's time: at least stale_timeout after it.
    count = len(h.messages('bms16/battery_state'))
    stale = h.wait(lambda: [m for m in h.messages('bms16/battery_state')[count:]
                            if not m.present], timeout=10.0)
    for msg in stale:
        assert stamp_seconds(msg) >= stamp_seconds(third) + 0.8


def test_a_never_heard_device_repeats_its_stale_message_with_a_new_stamp(rig_factory):
    # The stale message is built once and republished: only a never-heard stamp moves.
    h = rig_factory({'devices': ['bms16']}, topics={'bms16/battery_state': BatteryState})
    msgs = h.wait(lambda: [m for m in h.messages('bms16/battery_state') if not m.present][:3]
                  if len(h.messages('bms16/battery_state')) >= 3 else None, timeout=10.0)
    stamps = [stamp_seconds(m) for m in msgs]
    assert stamps[0] < stamps[1] < stamps[2], stamps
    assert all(math.isnan(m.voltage) and len(m.cell_voltage) == 16 for m in msgs)


def test_diagnostics_published_at_once_when_a_level_changes(rig_factory):
    # A 30 s period: only the at-once rule can explain arrays within seconds.
    h = rig_factory({'devices': ['bms16'], 'bms16.stale_timeout': 60.0,
                     'diagnostics_period': 30.0})
    h.wait(lambda: h.messages('/diagnostics'), timeout=5.0)
    assert level(h.status('bms16', timeout=0.1)) == 3  # never heard: STALE
    h.send(500, bms16_status(0, 80, 523, 125, 25))
    h.status('bms16', lambda s: level(s) == 0, timeout=3.0)
    h.send(500, bms16_status(3, 80, 523, 125, 25))  # overvoltage
    status = h.status('bms16', lambda s: level(s) == 2, timeout=3.0)
    assert 'CHARGE_DISABLED_OVERVOLTAGE' in status.message


def test_bridges_in_namespaces_name_their_diagnostics_apart(rig_factory):
    """Issue 18.4: /diagnostics is global; the namespace goes into every status name."""
    from command_rig import unique_channel
    channel = unique_channel('ns')  # one bus, one hardware_id: only the names differ
    car1 = rig_factory({'devices': ['bms16']}, channel=channel, namespace='car1')
    car2 = rig_factory({'devices': ['bms16']}, channel=channel, namespace='car2')
    plain = rig_factory({'devices': ['bms16']})
    car1.send(500, bms16_status(0, 80, 523, 125, 25))  # both bridges hear it

    def names(rig):
        return {s.name for array in rig.messages('/diagnostics') for s in array.status}
    expected = {f'{car}/ams_can_bridge: {part}' for car in ('car1', 'car2')
                for part in ('bms16', 'CAN bus')}
    car1.wait(lambda: names(car1) >= expected, what='the statuses of both cars')
    assert all(name in expected for name in names(car1)), names(car1)
    assert car1.status('bms16', lambda s: level(s) == 0).name == 'car1/ams_can_bridge: bms16'
    assert car2.status('bms16', lambda s: level(s) == 0).name == 'car2/ams_can_bridge: bms16'
    # without a namespace the names stay as config/diagnostics_aggregator.yaml expects
    plain.wait(lambda: {'ams_can_bridge: bms16', 'ams_can_bridge: CAN bus'} <= names(plain),
               what='the statuses of the bridge without a namespace')


def test_silent_ams_arrays_are_nan_and_stale_messages_are_stamped_when_published(rig_factory):
    """Issue 18.7: arrays follow present: false; its stamp is the publish time."""
    h = rig_factory({'devices': ['ams'], 'ams.stale_timeout': 0.5},
                    topics={'ams/battery_state': BatteryState,
                            'ams/temperatures': Float32MultiArray,
                            'ams/discharge_temperatures': Float32MultiArray})
    send_ams_bank(h)
    h.send(0x300, ams_status(AIR_PLUS | AIR_MINUS | (1 << 5) | DRIVE, 180, 28, 77, 1))
    alive = h.last('ams/battery_state', lambda m: m.present)
    temps = h.last('ams/temperatures', lambda m: not math.isnan(m.data[0]))
    assert list(temps.data) == approx_list([20, 21, 22, 23, 24, 25, 26, 27, 28, -5])
    topics = ('ams/battery_state', 'ams/temperatures', 'ams/discharge_temperatures')
    counts = {t: len(h.messages(t)) for t in topics}

    # the AMS falls silent: two present: false messages, each with NaN arrays beside it
    def silent() -> list[BatteryState]:
        return [m for m in h.messages('ams/battery_state')[counts['ams/battery_state']:]
                if not m.present]
    stale = h.wait(lambda: silent()[:2] if len(silent()) >= 2 else None, timeout=10.0)
    for topic, rows_cols in (('ams/temperatures', (1, 10)),
                             ('ams/discharge_temperatures', (1, 14))):
        msgs = h.wait(lambda t=topic: h.messages(t)[counts[t]:] or None, timeout=10.0)
        assert [d.size for d in msgs[-1].layout.dim] == list(rows_cols)
        assert all(math.isnan(v) for v in msgs[-1].data), (topic, list(msgs[-1].data))
    # stamped when published: at least stale_timeout after the last frame, never its time
    for msg in stale:
        assert stamp_seconds(msg) >= stamp_seconds(alive) + 0.5
        assert stamp_seconds(msg) <= time.time()
    # each republished message gets its own stamp (the message is built once, restamped)
    assert stamp_seconds(stale[1]) > stamp_seconds(stale[0])
    assert all(math.isnan(v) for v in stale[1].cell_voltage)


def test_negative_zero_is_published_as_zero(rig_factory):
    """Issue 18.7: the IVT-S's 0 A with discharge_positive is -0.0 * ... : published 0.0."""
    h = rig_factory({'devices': ['shunt'], 'shunt.type': 'ivt_s'},
                    topics={'shunt/battery_state': BatteryState})
    assert math.copysign(1.0, -1.0 * 0.0) < 0  # what the sign flip computes
    h.send(0x521, ivt(0, 0, 0))
    msg = h.last('shunt/battery_state', lambda m: m.present)
    assert msg.current == 0.0 and math.copysign(1.0, msg.current) > 0
