# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
SMA frames as real devices send them (issue "Field truth", doc/protocols.md section 5).

Every golden frame below is typed by hand from the public source named beside it, never
produced by our simulator or codec.
"""
import math

import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.sma.device import IDENTITY_TIMEOUT
from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.common import Frame, load_dbc
from ams_can_bridge.protocols.sma import SmaCodec, SmaFlag, SmaLimits, SmaSoc
from ams_can_bridge.protocols.sma_dialects import (
    keepalive_frame, PylontechRequest, VictronEnergy, VictronInstalledCapacity, VictronModules,
    VictronProductName)
from sma_golden import (BYD_351, BYD_355, BYD_356, BYD_35A, BYD_35F, BYD_372, BYD_378, BYD_379,
                        BYD_382, feed, make)

CODEC = SmaCodec()

# syssi/esphome-virtual-can-bms issue #3: candump of a Victron GX with a CAN-BMS battery.
GX_355 = bytes([0x3C, 0x00, 0x64, 0x00, 0x84, 0x17, 0x00, 0x00])  # 60 %, 100 %, 60.20 %
GX_35A = bytes([0xAA, 0xAA, 0xAA, 0x02, 0xAA, 0xAA, 0xAA, 0x02])
# stuartpittaway/diyBMSv4ESP32 victron_canbus.cpp: 0x355 and 0x379 with DLC 2 (a U16 each).
DIYBMS_355 = bytes([0x50, 0x00])  # 80 %
DIYBMS_379 = bytes([0x9C, 0x00])  # 156 Ah


# --- 1. 0x355: the high-resolution SoC only where it agrees ---------------------------------
def test_byd_zero_padding_publishes_the_integer_soc():
    soc = CODEC.decode(0x355, BYD_355)
    assert soc == SmaSoc(67, 100, 0.0)
    assert not soc.hires_used and soc.percent == 67.0
    device, _ = make()
    feed(device, (0x35F, BYD_35F), (0x355, BYD_355), (0x356, BYD_356))
    report = device.battery_report()
    assert report.percentage == pytest.approx(0.67)
    assert report.charge == pytest.approx(105 * 0.67)
    assert report.capacity == 105.0
    assert device.diagnostic_report().values['soc high resolution %'] == (
        'not used: 0 as sent (0 % at 0.01 %/bit, 0 % at 0.1 %/bit) is not within 1 % of the '
        'SoC 67 %')


def test_agreeing_high_resolution_soc_is_used():
    soc = CODEC.decode(0x355, GX_355)
    assert soc == SmaSoc(60, 100, 60.2) and soc.hires_used
    device, _ = make()
    feed(device, (0x355, GX_355), (0x356, BYD_356))
    assert device.battery_report().percentage == pytest.approx(0.602)


@pytest.mark.parametrize('hires_raw, used', [
    (6700 + 100, True), (6700 - 100, True), (6700 + 101, False), (6700 - 101, False),
    (0xFFFF, False)])
def test_high_resolution_soc_within_one_percent(hires_raw, used):
    data = bytes([0x43, 0x00, 0x64, 0x00, hires_raw & 0xFF, hires_raw >> 8])
    soc = CODEC.decode(0x355, data)
    assert soc.hires_used is used
    assert soc.percent == (hires_raw / 100 if used else 67.0)


def test_diybms_soc_only_frame_publishes_the_soc():
    soc = CODEC.decode(0x355, DIYBMS_355)
    assert soc == SmaSoc(80, None, None) and soc.percent == 80.0
    device, _ = make()
    feed(device, (0x355, DIYBMS_355), (0x356, BYD_356))
    assert device.battery_report().percentage == pytest.approx(0.8)
    assert device.diagnostic_report().values['soh %'] == 'not available'
    for dlc in (0, 1, 3):
        with pytest.raises(MalformedFrameError, match=f'DLC {dlc}'):
            CODEC.decode(0x355, BYD_355[:dlc])


# --- 2. charge = capacity x SoC, both known and fresh ------------------------------------------
def test_charge_needs_both_capacity_and_soc():
    device, clock = make()
    feed(device, (0x355, BYD_355), (0x356, BYD_356))
    report = device.battery_report()
    assert report.percentage == pytest.approx(0.67) and math.isnan(report.charge)
    device, clock = make()
    feed(device, (0x35F, BYD_35F), (0x356, BYD_356))
    report = device.battery_report()
    assert report.capacity == 105.0 and math.isnan(report.charge)


def test_charge_is_nan_once_soc_or_capacity_expired():
    device, clock = make()
    feed(device, (0x35F, BYD_35F), (0x355, BYD_355), (0x356, BYD_356))
    assert device.battery_report().charge == pytest.approx(70.35)
    clock.now += device.stale_timeout + 0.5  # 0x355 expired, 0x35F (identity) not yet
    feed(device, (0x356, BYD_356))
    report = device.battery_report()
    assert report.capacity == 105.0 and math.isnan(report.percentage)
    assert math.isnan(report.charge)
    feed(device, (0x355, BYD_355))
    assert device.battery_report().charge == pytest.approx(70.35)
    clock.now += IDENTITY_TIMEOUT + 0.5  # now 0x35F expired; a fresh SoC alone is no charge
    feed(device, (0x355, BYD_355), (0x356, BYD_356))
    report = device.battery_report()
    assert report.percentage == pytest.approx(0.67) and math.isnan(report.charge)


# --- 16. dialects --------------------------------------------------------------------------
def test_discharge_voltage_limit_absent_or_zero_is_no_limit():
    assert CODEC.decode(0x351, BYD_351) == SmaLimits(58.4, 128.0, 128.0, 43.0)
    # dalathegreat/Battery-Emulator PYLON-LV-CAN.cpp sends 0x351 with DLC 6.
    assert CODEC.decode(0x351, BYD_351[:6]).discharge_voltage_v is None
    assert CODEC.decode(0x351, BYD_351[:7]).discharge_voltage_v is None  # half a field
    zero = CODEC.decode(0x351, BYD_351[:6] + bytes(2))
    assert zero.discharge_voltage_v is None and zero.charge_voltage_v == 58.4
    device, _ = make()
    feed(device, (0x351, BYD_351[:6] + bytes(2)), (0x356, BYD_356))
    assert device.diagnostic_report().values['discharge voltage limit V'] == 'not available'


@pytest.mark.parametrize('byte0, wanted', [
    # ArminJo/JK-BMSToPylontechCAN Pylontech_CAN.h: bit 7 charge enable, 6 discharge
    # enable, 5 force charge request I, 4 force charge request II, 3 full charge request.
    (0xC0, PylontechRequest(True, True)),
    (0xA0, PylontechRequest(True, False, True)),
    (0xD0, PylontechRequest(True, True, False, True, False)),
    (0xC8, PylontechRequest(True, True, False, False, True)),
    (0x18, PylontechRequest(False, False, False, True, True)),
])
def test_pylontech_0x35c_force_charge_ii_and_full_charge(byte0, wanted):
    assert CODEC.decode(0x35C, bytes([byte0, 0x00])) == wanted
    assert CODEC.encode(wanted) == Frame(0x35C, bytes([byte0, 0x00]))


def test_pylontech_0x35c_bits_in_the_diagnostics():
    device, _ = make()
    feed(device, (0x35C, bytes([0xD8, 0x00])))
    values = device.diagnostic_report().values
    assert values['force charge request II'] == 'yes'
    assert values['full charge request'] == 'yes'
    assert values['request charge immediately'] == 'no'


def test_victron_0x372_with_dlc_2():
    assert CODEC.decode(0x372, bytes([0x02, 0x00])) == VictronModules(2, None, None, None)
    assert CODEC.decode(0x372, BYD_372) == VictronModules(2, 2, 1, 0)
    for dlc in (0, 1, 3):
        with pytest.raises(MalformedFrameError, match=f'DLC {dlc}'):
            CODEC.decode(0x372, BYD_372[:dlc])


def test_0x35a_byte7_bits_2_3_are_the_online_status_not_a_warning():
    byd = CODEC.decode(0x35A, BYD_35A)
    assert byd.online is True and not byd.active_warnings and not byd.active_alarms
    assert CODEC.decode(0x35A, GX_35A).online is None  # pair 0: not sent
    # the same pair with code 1 ("active" in SMA's reading): offline, and no warning
    offline = CODEC.decode(0x35A, BYD_35A[:7] + bytes([0xA6]))
    assert offline.online is False
    assert offline.warnings['reserved1'] is SmaFlag.NOT_SUPPORTED
    assert offline.active_warnings == ()
    device, _ = make()
    feed(device, (0x35A, BYD_35A[:7] + bytes([0xA6])), (0x356, BYD_356))
    report = device.diagnostic_report()
    assert report.level == Level.OK and 'warnings' not in report.message
    assert report.values['system status (0x35A byte 7)'] == 'offline'
    feed(device, (0x35A, BYD_35A))
    assert device.diagnostic_report().values['system status (0x35A byte 7)'] == 'online'
    assert CODEC.encode(byd) == Frame(0x35A, BYD_35A)


# stuartpittaway/diyBMSv4ESP32 victron_message_35f (commit 90dca048): byte 2 the build's year,
# byte 3 its week; 0 Ah. Built here for year 23, week 45 (0x17, 0x2D).
DIYBMS_35F = bytes([0x00, 0x00, 0x17, 0x2D, 0x00, 0x00])


@pytest.mark.parametrize('data, shown', [
    # dfch/BydCanProtocol: "01 17" from a battery its README calls "B019 / v1.23"
    (BYD_35F, '1.23 (bytes 2-3: 01 17)'),
    (DIYBMS_35F, '23.45 (bytes 2-3: 17 2D)'),
])
def test_0x35f_bms_version_is_byte_2_major_byte_3_minor(data, shown):
    device, _ = make()
    feed(device, (0x35F, data))
    assert device.diagnostic_report().values['bms version'] == shown


def test_victron_energy_capacity_and_product_name():
    assert CODEC.decode(0x378, BYD_378) == VictronEnergy(211.2, 183.5)
    assert CODEC.decode(0x379, BYD_379) == VictronInstalledCapacity(156)
    assert CODEC.decode(0x379, DIYBMS_379) == VictronInstalledCapacity(156)
    assert CODEC.decode(0x382, BYD_382) == VictronProductName('PREMIUM')
    assert CODEC.encode(VictronEnergy(211.2, 183.5)) == Frame(0x378, BYD_378)
    assert CODEC.decode(0x378, BYD_378[:4]) == VictronEnergy(211.2, None)
    assert CODEC.decode(0x378, bytes([0xFF] * 8)) == VictronEnergy(None, None)
    # A field sent in part is not sent: DLC 5 is the charged energy (0x840 = 211.2 kWh) and
    # one byte of the discharged one, which must not read as 0xFFFFFF2B x 0.1 kWh.
    assert CODEC.decode(0x378, bytes([0x40, 0x08, 0x00, 0x00, 0x2B])) \
        == VictronEnergy(211.2, None)
    assert CODEC.decode(0x378, bytes([0x40, 0x08, 0x00, 0x00, 0x2B, 0x07, 0x00])) \
        == VictronEnergy(211.2, None)
    for can_id, dlc in ((0x378, 3), (0x379, 1), (0x382, 0)):
        with pytest.raises(MalformedFrameError, match=f'DLC {dlc}'):
            CODEC.decode(can_id, bytes(dlc))
    device, _ = make()
    feed(device, (0x378, BYD_378), (0x379, BYD_379), (0x382, BYD_382), (0x356, BYD_356))
    values = device.diagnostic_report().values
    assert values['energy charged kWh'] == '211.2'
    assert values['energy discharged kWh'] == '183.5'
    assert values['installed capacity Ah'] == '156'
    assert values['product name'] == 'PREMIUM'
    # no 0x35F: the capacity is the installed capacity of 0x379 (issue "Field truth II", 2)
    assert device.battery_report().capacity == 156
    feed(device, (0x35F, BYD_35F))
    assert device.battery_report().capacity == 105  # 0x35F's own capacity comes first


def test_dbc_decodes_the_new_frames_as_the_codec():
    db = load_dbc('sma')
    energy = db.decode_message(0x378, BYD_378)
    assert energy['ChargedEnergy'] == pytest.approx(211.2)
    assert energy['DischargedEnergy'] == pytest.approx(183.5)
    assert db.decode_message(0x379, BYD_379[:2])['InstalledCapacity'] == 156
    assert db.decode_message(0x35C, bytes([0x18, 0]), decode_choices=False) == {
        'ChargeEnable': 0, 'DischargeEnable': 0, 'RequestChargeImmediately': 0,
        'ForceChargeRequestII': 1, 'FullChargeRequest': 1}
    alarms = db.decode_message(0x35A, BYD_35A[:7] + bytes([0xA6]), decode_choices=False)
    assert alarms['SystemOnline'] == 1


# --- 13. the keep-alive frame ---------------------------------------------------------------
def test_keepalive_frame_is_0x305_with_eight_zero_bytes():
    # Pylontech CAN protocol V1.2, quoted in ArminJo/JK-BMSToPylontechCAN:
    # "Inverter reply every second: 0x305: 00-00-00-00-00-00-00-00"
    assert keepalive_frame() == Frame(0x305, bytes([0, 0, 0, 0, 0, 0, 0, 0]))
    device, _ = make()
    assert device.keepalive_frame() == Frame(0x305, bytes(8))
    assert 0x305 not in device.arbitration_ids  # the bridge sends it, never consumes it
