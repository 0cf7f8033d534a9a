# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What the devices really send, end to end through the bridge node on python-can 'virtual'.

Frames are written by hand from the facts of issue 10 (Pylontech / Victron dialects of the
SMA protocol); a real subscriber receives the BatteryState and /diagnostics the node publishes.
"""
from __future__ import annotations

import os

from rclpy.parameter import Parameter
import pytest
from sensor_msgs.msg import BatteryState

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.ros.bridge_node import BridgeNode
from helpers import ros_context
from shared import level, values


def le16(*numbers: int) -> bytes:
    return b''.join((n & 0xFFFF).to_bytes(2, 'little') for n in numbers)


def test_sma_pylontech_dialect_through_the_node(rig_factory):
    h = rig_factory({'devices': ['bms'], 'bms.type': 'sma', 'diagnostics_period': 0.2},
                    topics={'bms/battery_state': BatteryState})
    h.send(0x351, le16(552, 500, 1000, 480))  # 55.2 / 48.0 V limits: 0x356 is in 0.01 V
    h.send(0x355, le16(64, 98))
    h.send(0x359, bytes([0b0000_0100, 0, 0, 0b0000_0001, 2]))  # under-voltage alarm,
    h.send(0x35C, bytes([0b1000_0000, 0]))  # charge over-current warning; charge enable only
    h.send(0x356, le16(4620, -153, 0x8000))  # 46.2 V, -15.3 A, no temperature
    msg = h.last('bms/battery_state', lambda m: m.present)
    assert msg.voltage == pytest.approx(46.2) and msg.percentage == pytest.approx(0.64)
    assert msg.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_DEAD
    status = h.status('bms', lambda s: level(s) == 2)
    assert status.message.startswith('alarms low_voltage; warnings high_charge_current')
    got = values(status)
    assert got['module count'] == '2'
    assert (got['charge enable'], got['discharge enable']) == ('yes', 'no')


@pytest.mark.parametrize('setting', [0.1, '0.1'])
def test_sma_voltage_scale_as_a_yaml_number_or_string(rig_factory, setting):
    # a Discover Lynx II's 0x356 (ai-republic/bms-to-inverter issue 107): 522 = 52.2 V
    h = rig_factory({'devices': ['sma'], 'sma.voltage_scale': setting,
                     'diagnostics_period': 0.2}, topics={'sma/battery_state': BatteryState})
    h.send(0x356, bytes([0x0A, 0x02, 0x11, 0xFF, 0xBE, 0x00, 0x00, 0x00]))
    msg = h.last('sma/battery_state', lambda m: m.present)
    assert msg.voltage == pytest.approx(52.2)  # no 0x351 needed: the parameter says 0.1
    status = h.status('sma', lambda s: 'voltage scale (0x356)' in values(s))
    assert values(status)['voltage scale (0x356)'] == '0.1 V/bit (sma.voltage_scale)'


def test_a_voltage_scale_that_is_none_of_its_choices_stops_the_bridge():
    params = {'can.interface': 'virtual', 'can.channel': f'scale-{os.getpid()}',
              'devices': ['sma'], 'sma.voltage_scale': 0.5}
    with ros_context() as context:
        with pytest.raises(ConfigError, match=r"sma.voltage_scale = '0.5' is not allowed: "
                                              r'use one of auto, 0.01, 0.1'):
            BridgeNode(context=context, namespace='scale_choice', parameter_overrides=[
                Parameter(k, value=v) for k, v in params.items()])


def test_sma_victron_dialect_through_the_node(rig_factory):
    h = rig_factory({'devices': ['sma'], 'diagnostics_period': 0.2},
                    topics={'sma/battery_state': BatteryState})
    h.send(0x35A, bytes([0xAA] * 8))  # every condition OK
    h.send(0x370, b'ACME BAT')
    h.send(0x371, b'TERY')
    h.send(0x372, le16(3, 0, 1, 0))
    h.send(0x373, le16(3287, 3341, 296, 304))  # 3.287 V, 3.341 V, 22.85 degC, 30.85 degC
    h.send(0x375, b'M2C7')
    h.send(0x356, le16(5120, 100, 0x8000))  # 51.2 V, +10.0 A (charging), no temperature
    msg = h.last('sma/battery_state', lambda m: m.present)
    assert msg.temperature == pytest.approx(30.85)  # the hottest cell, from 0x373
    assert msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_CHARGING
    status = h.status('sma', lambda s: 'max cell voltage id' in values(s))
    got = values(status)
    assert got['bms name'] == 'ACME BATTERY'
    assert (got['min cell voltage V'], got['max cell voltage V']) == ('3.287', '3.341')
    assert got['max cell temperature degC'] == '30.85'
    assert got['modules blocking discharge'] == '1' and got['max cell voltage id'] == 'M2C7'
    assert level(status) == 0


# --- EVMS3 bus: TC chargers (29-bit) and balance requests --------------------------------------
# RUNNING, no error, 100.0 Ah, 400.0 V, aux 13.0 V, isolation 100 %, 25 degC
EVMS3_RUNNING = bytes.fromhex('02 03 E8 0F A0 82 64 41')
# CHARGING with error 12 (isolation): must never be what an 11-bit EVMS3 shows
EVMS3_CHARGING_ISOLATION = bytes.fromhex('63 03 E8 0F A0 82 64 41')


def test_evms3_chargers_and_balance_through_the_node(rig_factory):
    h = rig_factory({'devices': ['evms3'], 'evms3.bms12_modules': 1, 'diagnostics_period': 0.2})
    h.send(30, EVMS3_RUNNING, extended=True)
    h.send(300, bytes([0x0F, 0xD2]), extended=True)  # module 0: balance to 4050 mV
    h.send(0x1806E5F4, bytes([0x0F, 0xC0, 0x00, 0x7D, 0x00, 0, 0, 0]), extended=True)
    # charger 1: 398.7 V, 9.8 A, over-temperature shutdown (bit 1)
    h.send(0x18FF50E5, bytes([0x0F, 0x93, 0x00, 0x62, 0x02, 0x41, 0, 0]), extended=True)
    status = h.status('evms3', lambda s: 'charger 1 status' in values(s))
    assert level(status) == 1
    # (module 0 sent no cells, so it is also reported silent)
    assert status.message.startswith('RUNNING, no error; ')
    assert status.message.endswith('; charger 1: over-temperature shutdown')
    got = values(status)
    assert (got['charger 1 target volts (V)'], got['charger 1 target amps (A)']) == (
        '403.2', '12.5')
    assert (got['charger 1 output volts (V)'], got['charger 1 output amps (A)']) == (
        '398.7', '9.8')
    assert got['charger 1 shutdown by BMS'] == 'no'
    assert got['charger 1 over-temperature shutdown'] == 'yes'
    assert got['module 0 balance target (mV)'] == '4050'


def test_evms3_on_11_bit_ids_with_29_bit_chargers(rig_factory):
    h = rig_factory({'devices': ['evms3'], 'evms3.extended_id': False, 'diagnostics_period': 0.2})
    h.send(30, EVMS3_CHARGING_ISOLATION, extended=True)  # another node's 29-bit ID 30
    h.send(30, EVMS3_RUNNING, extended=False)
    h.send(0x18FF50E5, bytes([0x0F, 0x93, 0x00, 0x62, 0x00, 0x41]), extended=True)
    status = h.status('evms3', lambda s: 'charger 1 status' in values(s))
    got = values(status)
    assert got['state'] == 'RUNNING' and got['error'] == 'no error'
    assert got['charger 1 output amps (A)'] == '9.8' and got['charger 1 status'] == 'OK'
    assert got['frames received'] == '2' and got['frames malformed'] == '0'
