# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
SMA-family frames as real batteries send them, part II (doc/protocols.md section 5).

Issue "Field truth II", points 1, 2 and 4; issue "Hardened" 26.7 for the SMA frames.

Every golden frame below is typed by hand from the public source named beside it (a capture
or a vendor's own code), never produced by our simulator or codec.
"""
import math

import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.sma.device import SmaDevice
from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.sma import SmaBatteryInfo, SmaCodec, SmaLimits
from ams_can_bridge.protocols.sma_dialects import (
    PylontechCellExtremes, PylontechCellIds, VictronBmsName, VictronCellExtremes,
    VictronInstalledCapacity)
from ams_can_bridge.protocols.sma_scale import decide_voltage_scale, raw_voltage
from helpers import Clock

CODEC = SmaCodec()

# ai-republic/bms-to-inverter issue 107: candump of a Discover Lynx II gateway ("Serial CAN")
# with three Discover AES batteries. The project's Discover reader takes 0x356 in 0.1 V.
DISCOVER_351 = bytes([0x2E, 0x02, 0x04, 0x0B, 0x04, 0x0B, 0xB0, 0x01])  # 55.8 V .. 43.2 V
DISCOVER_355 = bytes([0x3E, 0x00, 0x64, 0x00, 0x00, 0x00, 0x00, 0x00])  # 62 %, 100 %
DISCOVER_356 = bytes([0x0A, 0x02, 0x11, 0xFF, 0xBE, 0x00, 0x00, 0x00])  # 522, -23.9 A, 19 C
DISCOVER_35A = bytes([0xAB, 0xAA, 0xFE, 0xAF, 0xAA, 0xFA, 0xFF])  # DLC 7
DISCOVER_370 = bytes([0x44, 0x69, 0x73, 0x63, 0x6F, 0x76, 0x65, 0x72])  # "Discover"
DISCOVER_371 = bytes([0x20, 0x41, 0x45, 0x53, 0x00, 0x00, 0x00, 0x00])  # " AES"
DISCOVER_373 = bytes([0x01, 0x00, 0x00, 0x00])  # DLC 4
# erikhedb/WE-EV-CAN-Dashboard logs/pcan/candump-2025-11-22_161709.log: an Orion BMS 2's
# SMA-compatible output in a car (72 cells; its own 0x6B0 says 282.4 V at another moment).
ORION_351 = bytes([0xAC, 0x0B, 0x64, 0x00, 0x10, 0x04, 0x00, 0x09])  # 298.8 V .. 230.4 V
ORION_356 = bytes([0x6E, 0x0B, 0x00, 0x00, 0xA0, 0x00])  # 2926: 292.6 V, 0 A, 16.0 C
# finitor/power-system docs/research/ecoworthy-can-interface.md: passive capture of an
# Eco-Worthy Cubix 100 (Pylon CAN protocol V2.0.6 by default), 2026-05-29.
ECO_351 = bytes([0x48, 0x02, 0xD0, 0x07, 0xD0, 0x07, 0xC0, 0x01])  # 58.4 V .. 44.8 V
ECO_355 = bytes([0x1E, 0x00, 0x64, 0x00, 0x00, 0x00, 0x00, 0x00])  # 30 %, 100 %
ECO_356 = bytes([0x79, 0x14, 0x00, 0x00, 0x71, 0x00, 0x00, 0x00])  # 5241: 52.41 V, 11.3 C
ECO_35F = bytes([0x00, 0x00, 0x0D, 0x05, 0x00, 0x00, 0x00, 0x00])  # capacity 0
ECO_370 = bytes([0x76, 0x00, 0x6C, 0x00, 0xCF, 0x0C, 0xCA, 0x0C])
ECO_371 = bytes([0x04, 0x01, 0x02, 0x02, 0x06, 0x02, 0x04, 0x02])
ECO_373 = bytes([0xCA, 0x0C, 0xCF, 0x0C, 0x1B, 0x01, 0x1C, 0x01])  # 3274, 3279 mV, 283, 284 K
ECO_374 = bytes([0x30, 0x32, 0x30, 0x34, 0x00, 0x00, 0x00, 0x00])  # "0204"
ECO_375 = bytes([0x30, 0x32, 0x30, 0x36, 0x00, 0x00, 0x00, 0x00])  # "0206"
ECO_379 = bytes([0xC8, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00])  # 200 Ah
# stuartpittaway/diyBMSv4ESP32 issue 87 (and pylon_canbus.cpp at 2f43aa8f, "negative
# number" for the discharge limit, removed two days later): a work-in-progress sender.
DIYBMS_WIP_351 = bytes([0x44, 0x02, 0x64, 0x00, 0x9C, 0xFF, 0x3F, 0x02])  # -10.0 A
# issue "Hardened" 26.7: 0x356 at -132.57 V (-13257 = 0xCC37) / 1,047.6 degC (0x28EC)
NEGATIVE_356 = bytes([0x37, 0xCC, 0x00, 0x00, 0x71, 0x00])
HOT_356 = bytes([0x79, 0x14, 0x00, 0x00, 0xEC, 0x28])


def make(config=None):
    clock = Clock(50.0)
    return SmaDevice('sma', config or {}, clock=clock), clock


def feed(device, *frames):
    for can_id, data in frames:
        device.handle_frame(can_id, data, 1.0)


# --- 1. 0x356 in 0.1 V -------------------------------------------------------------------
def test_discover_voltage_is_0_1_v_by_its_own_limits():
    battery = CODEC.decode(0x356, DISCOVER_356)
    assert raw_voltage(battery) == 522
    assert CODEC.decode(0x351, DISCOVER_351) == SmaLimits(55.8, 282.0, 282.0, 43.2)
    decision = decide_voltage_scale(522, CODEC.decode(0x351, DISCOVER_351))
    assert decision.scale == 0.1
    assert decision.reason == ('52.2 V at 0.1 V/bit fits the 0x351 limits 43.2..55.8 V, '
                               '5.22 V at 0.01 V/bit does not')


def test_orion_voltage_is_0_1_v_by_its_own_limits():
    limits = CODEC.decode(0x351, ORION_351)
    assert limits == SmaLimits(298.8, 10.0, 104.0, 230.4)
    assert decide_voltage_scale(raw_voltage(CODEC.decode(0x356, ORION_356)), limits).scale \
        == 0.1
    device, _ = make()
    feed(device, (0x351, ORION_351), (0x356, ORION_356))
    assert device.battery_report().voltage == 292.6


def test_sma_scale_batteries_stay_at_0_01_v():
    # the Eco-Worthy and a BYD LVS (dfch/BydCanProtocol: 53.10 V within 43.0..58.4 V)
    assert decide_voltage_scale(5241, CODEC.decode(0x351, ECO_351)).scale == 0.01
    byd_351 = bytes([0x48, 0x02, 0x00, 0x05, 0x00, 0x05, 0xAE, 0x01])
    assert decide_voltage_scale(5310, CODEC.decode(0x351, byd_351)).scale == 0.01
    device, _ = make()
    feed(device, (0x351, ECO_351), (0x356, ECO_356))
    assert device.battery_report().voltage == 52.41


def test_voltage_unknown_until_the_first_0x351_then_why_in_the_diagnostics():
    device, _ = make()
    feed(device, (0x356, DISCOVER_356))
    report = device.battery_report()
    assert report.present and math.isnan(report.voltage) and report.current == -23.9
    diag = device.diagnostic_report()
    assert diag.level == Level.OK  # waiting is not a fault
    assert diag.values['voltage V'] == 'unknown' and 'voltage unknown' in diag.message
    assert diag.values['voltage scale (0x356)'].startswith('unknown until 0x351')
    feed(device, (0x351, DISCOVER_351))
    assert device.battery_report().voltage == 52.2
    diag = device.diagnostic_report()
    assert diag.values['voltage V'] == '52.2' and '52.2 V' in diag.message
    assert diag.values['voltage scale (0x356)'] == (
        '0.1 V/bit (auto: 52.2 V at 0.1 V/bit fits the 0x351 limits 43.2..55.8 V, '
        '5.22 V at 0.01 V/bit does not)')


def test_the_decision_is_kept_when_0x351_stops():
    device, clock = make()
    feed(device, (0x351, DISCOVER_351), (0x356, DISCOVER_356))
    clock.now += device.stale_timeout + 1.0  # 0x351 expired: the evidence stays decided
    feed(device, (0x356, DISCOVER_356))
    assert device.battery_report().voltage == 52.2
    diag = device.diagnostic_report()
    assert diag.level == Level.OK and 'voltage_scale' not in diag.message
    assert diag.values['frames expired'].startswith('0x351')


def test_never_any_evidence_gives_sma_0_01_v_with_a_warn_naming_the_parameter():
    device, clock = make()
    feed(device, (0x35A, bytes([0xAA] * 8)), (0x356, DISCOVER_356))
    clock.now += device.stale_timeout  # the wait: one stale_timeout after the first 0x356
    feed(device, (0x35A, bytes([0xAA] * 8)), (0x356, DISCOVER_356))
    assert device.battery_report().voltage == 5.22  # SMA's scale, and said so:
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN
    assert ("0x356 voltage scale assumed SMA's 0.01 V (no 0x351 voltage limits within 5 s): "
            'set sma.voltage_scale to 0.01 or 0.1') in diag.message
    # the parameter settles it: 0.1 as YAML writes it (a number) or as a string
    for setting in (0.1, '0.1'):
        device.configure({'voltage_scale': setting})
        assert device.battery_report().voltage == 52.2
        diag = device.diagnostic_report()
        assert diag.level == Level.OK
        assert diag.values['voltage scale (0x356)'] == '0.1 V/bit (sma.voltage_scale)'


def test_a_late_0x351_still_settles_an_assumed_scale():
    device, clock = make()
    feed(device, (0x356, DISCOVER_356))
    clock.now += device.stale_timeout
    assert device.battery_report().voltage == 5.22
    feed(device, (0x351, DISCOVER_351))
    assert device.battery_report().voltage == 52.2
    assert 'voltage_scale' not in device.diagnostic_report().message


def test_voltage_scale_refuses_other_values():
    for bad in ('0.001', 1, 'tenth'):
        with pytest.raises(ValueError, match='sma.voltage_scale .* use one of auto, 0.01, 0.1'):
            make({'voltage_scale': bad})


def test_cell_evidence_and_cell_count():
    # The Eco-Worthy's own cells (0x373: 3.274..3.279 V) fit 52.41 V (16 cells) and 524.1 V
    # (160 cells) alike: only the limits settle it; with its cell count (16) so do cells.
    cells = (3.274, 3.279)
    assert decide_voltage_scale(5241, None, cells).scale is None
    assert decide_voltage_scale(5241, None, cells, cell_count=16).scale == 0.01
    # A 0.1 V sender read at 0.01 V is 5.22 V: 1.6 of those cells, no whole number
    # (the Discover's 522 with the Eco-Worthy's cell voltages: the arithmetic, not a capture).
    decision = decide_voltage_scale(522, None, cells)
    assert decision.scale == 0.1 and 'cells of 3.274..3.279 V' in decision.reason
    assert decide_voltage_scale(522, None, None, cell_count=16).scale == 0.1
    assert decide_voltage_scale(522).scale is None


# --- 2. 0x35F capacity 0 is "not sent" -------------------------------------------------------
def test_capacity_zero_is_not_sent_and_0x379_gives_the_capacity():
    assert CODEC.decode(0x35F, ECO_35F) == SmaBatteryInfo(0, 0x050D, None)
    device, _ = make()
    feed(device, (0x351, ECO_351), (0x35F, ECO_35F), (0x355, ECO_355), (0x356, ECO_356))
    report = device.battery_report()
    assert math.isnan(report.capacity) and math.isnan(report.design_capacity)
    assert math.isnan(report.charge) and report.percentage == pytest.approx(0.30)
    assert device.diagnostic_report().values['capacity Ah'] == 'not available'
    feed(device, (0x379, ECO_379))
    report = device.battery_report()
    assert report.capacity == report.design_capacity == 200.0
    assert report.charge == pytest.approx(60.0)
    assert CODEC.decode(0x379, bytes(2)) == VictronInstalledCapacity(None)  # 0 Ah: none


# --- 4. binary 0x370 / 0x371, 0x373 DLC 4, negative limits -----------------------------------
def test_pylontech_v2_binary_cell_extremes_are_decoded_not_shown_as_a_name():
    extremes = CODEC.decode(0x370, ECO_370)
    assert extremes == PylontechCellExtremes(11.8, 10.8, 3.279, 3.274)
    # the same battery's Victron 0x373 agrees: 3274 / 3279 mV
    assert CODEC.decode(0x373, ECO_373) == VictronCellExtremes(3.274, 3.279, 283, 284)
    assert CODEC.decode(0x371, ECO_371) == PylontechCellIds(0x0104, 0x0202, 0x0206, 0x0204)
    device, _ = make()
    feed(device, (0x370, ECO_370), (0x371, ECO_371), (0x374, ECO_374), (0x375, ECO_375),
         (0x351, ECO_351), (0x356, ECO_356))
    values = device.diagnostic_report().values
    assert 'bms name' not in values  # no garbled "v l" name any more
    assert values['max cell voltage V (0x370)'] == '3.279'
    assert values['min cell voltage V (0x370)'] == '3.274'
    assert values['max cell temperature degC (0x370)'] == '11.8'
    # 0x371's ids are the 0x374 / 0x375 text ids: module 02 cell 06 and cell 04
    assert values['max voltage cell (0x371)'] == values['max cell voltage id'] == '0206'
    assert values['min voltage cell (0x371)'] == values['min cell voltage id'] == '0204'


def test_a_printable_0x370_is_still_the_victron_name():
    assert CODEC.decode(0x370, DISCOVER_370) == VictronBmsName(1, 'Discover')
    assert CODEC.decode(0x371, DISCOVER_371) == VictronBmsName(2, ' AES')
    device, _ = make()
    feed(device, (0x370, DISCOVER_370), (0x371, DISCOVER_371), (0x35A, DISCOVER_35A))
    assert device.diagnostic_report().values['bms name'] == 'Discover AES'
    assert device.frames_malformed == 0


def test_discover_0x373_with_dlc_4_is_malformed_with_its_reason():
    with pytest.raises(MalformedFrameError, match=r'DLC 4, expected 8: min/max cell voltage '
                                                  r'and temperature are 8 bytes'):
        CODEC.decode(0x373, DISCOVER_373)
    device, _ = make()
    feed(device, (0x373, DISCOVER_373))
    assert device.frames_malformed == 1
    assert 'a Discover Lynx II sends 4' in device.diagnostic_report().values[
        'last malformed frame']


def test_a_negative_current_limit_is_malformed_never_a_limit():
    with pytest.raises(MalformedFrameError, match='discharge current limit -10 A is negative'):
        CODEC.decode(0x351, DIYBMS_WIP_351)
    device, _ = make()
    feed(device, (0x351, DIYBMS_WIP_351), (0x356, ECO_356))
    values = device.diagnostic_report().values
    assert device.frames_malformed == 1 and 'charge voltage limit V' not in values
    assert values['voltage scale (0x356)'].startswith('unknown until 0x351')


# --- 26.7: impossible 0x356 values ----------------------------------------------------------
@pytest.mark.parametrize('data, reason', [
    (NEGATIVE_356, r'pack voltage -132.57 V \(at 0.01 V/bit\) is negative'),
    (HOT_356, r'temperature 1047.6 degC is outside -273.15..200 degC'),
])
def test_an_impossible_battery_frame_is_counted_never_published(data, reason):
    with pytest.raises(MalformedFrameError, match=reason):
        CODEC.decode(0x356, data)
    device, _ = make()
    assert not device.handle_frame(0x356, data, 1.0)
    assert device.frames_malformed == 1 and not device.battery_report().present
    # 200 degC is the hottest a battery may read, 200.1 degC is not
    assert CODEC.decode(0x356, HOT_356[:4] + (2000).to_bytes(2, 'little')).temperature_c \
        == 200.0
    with pytest.raises(MalformedFrameError, match='200.1 degC'):
        CODEC.decode(0x356, HOT_356[:4] + (2001).to_bytes(2, 'little'))
