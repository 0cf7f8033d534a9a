"""
What the devices really send, end to end through the bridge node on python-can 'virtual'.

Frames are written by hand from the facts of issue 10 (Pylontech / Victron dialects of the
SMA protocol); a real subscriber receives the BatteryState and /diagnostics the node publishes.
"""
from __future__ import annotations

import pytest
from sensor_msgs.msg import BatteryState

from test_bridge_node import context, harness, level, values  # noqa: F401 (fixtures)


def le16(*numbers: int) -> bytes:
    return b''.join((n & 0xFFFF).to_bytes(2, 'little') for n in numbers)


def test_sma_pylontech_dialect_through_the_node(harness):  # noqa: F811
    h = harness({'devices': ['bms'], 'bms.type': 'sma', 'diagnostics_period': 0.2},
                {'bms/battery_state': BatteryState})
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


def test_sma_victron_dialect_through_the_node(harness):  # noqa: F811
    h = harness({'devices': ['sma'], 'diagnostics_period': 0.2},
                {'sma/battery_state': BatteryState})
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
