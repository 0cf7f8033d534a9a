"""
SMA-family frames as real batteries send them, part III (issue 35, points 1 and 2).

Every golden frame below is typed by hand from the public source named beside it (a capture
or a vendor's own code), never produced by our simulator or codec (doc/protocols.md 5.2).
"""
import pytest

from ams_can_bridge.devices.sma import SmaDevice
from ams_can_bridge.protocols.sma import SmaCodec
from helpers import Clock

CODEC = SmaCodec()

# erikhedb/WE-EV-CAN-Dashboard logs/canbus.json at d1eec4fd (2025-11-05): an Orion BMS 2's
# SMA-compatible output in a car. Its own DBC (docs/ZeroEvDBC(onlyBMS&DU).dbc) has
# HvBatterySOChighdef 32|16 at 0.1 %; its 0x6B0 at the same moment: 00 A7 = 167 x 0.5 %.
ORION_355_835 = bytes([0x53, 0x00, 0x64, 0x00, 0x43, 0x03, 0x06, 0x18])  # 83 %, 835
ORION_6B0_SOC_PCT = 0xA7 * 0.5  # 83.5
# the same car, logs/pcan/candump-2025-11-22_161709.log at 7531a6db: 95 %, 950
ORION_355_950 = bytes([0x5F, 0x00, 0x64, 0x00, 0xB6, 0x03, 0x06, 0x18])
# the same car, logs/canbus.json at 4163240c (2025-09-26): 80 %, 895, while its 0x6B0 says
# 00 A1 = 80.5 %: bytes 4-5 agree with the SoC at no scale, so they are not used.
ORION_355_895 = bytes([0x50, 0x00, 0x64, 0x00, 0x7F, 0x03, 0x06, 0x18])
ORION_351 = bytes([0xAC, 0x0B, 0x64, 0x00, 0x10, 0x04, 0x00, 0x09])  # 298.8 V .. 230.4 V
ORION_356 = bytes([0x6E, 0x0B, 0x00, 0x00, 0xA0, 0x00])  # 292.6 V at 0.1 V


def make():
    clock = Clock(50.0)
    return SmaDevice('sma', {}, clock=clock), clock


def feed(device, *frames):
    for can_id, data in frames:
        device.handle_frame(can_id, data, 1.0)


# --- 35.2: 0x355 bytes 4-5 in 0.01 % or 0.1 %, decided against bytes 0-1 -------------------
def test_orion_high_resolution_soc_in_tenths_is_published_as_83_5():
    soc = CODEC.decode(0x355, ORION_355_835)
    assert soc.hires_raw == 835 and soc.hires_scale == 0.1
    assert soc.percent == pytest.approx(ORION_6B0_SOC_PCT)
    device, _ = make()
    feed(device, (0x351, ORION_351), (0x355, ORION_355_835), (0x356, ORION_356))
    assert device.battery_report().percentage == pytest.approx(0.835)
    values = device.diagnostic_report().values
    assert values['soc high resolution %'] == '83.5'
    assert values['soc high resolution scale'] == '0.1 %/bit (agrees with the SoC 83 %)'
    assert '8.35' not in ' '.join(values.values())


def test_orion_95_percent():
    assert CODEC.decode(0x355, ORION_355_950).percent == pytest.approx(95.0)


def test_high_resolution_soc_agreeing_at_no_scale_is_not_used():
    soc = CODEC.decode(0x355, ORION_355_895)
    assert soc.hires_scale is None and soc.percent == 80.0
    device, _ = make()
    feed(device, (0x355, ORION_355_895), (0x356, ORION_356))
    assert device.battery_report().percentage == pytest.approx(0.80)
    assert device.diagnostic_report().values['soc high resolution %'] == (
        'not used: 895 as sent (8.95 % at 0.01 %/bit, 89.5 % at 0.1 %/bit) is not within 1 % '
        'of the SoC 80 %')


def test_sma_hundredths_still_win_where_both_could_agree():
    # SoC 0 with 5 as sent: 0.05 % and 0.5 % both within 1 %: SMA's own 0.01 %/bit
    soc = CODEC.decode(0x355, bytes([0, 0, 100, 0, 5, 0]))
    assert soc.hires_scale == 0.01 and soc.percent == pytest.approx(0.05)
