# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
TC/Elcon chargers on the EVMS3 bus, and the EVMS3 on 11-bit IDs next to them.

Golden frames written by hand from the facts of issue 10 (ZEVA's EVMS3 firmware IDs, the
TC/Elcon byte layout), not produced by the encoder; the codec and evms3.dbc are checked
against them.
"""
import cantools
import pytest

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.common import msg_defs_dir
from ams_can_bridge.protocols.evms3 import Bms12Request, Evms3Codec, ResetSoc
from ams_can_bridge.protocols.tc_charger import (
    ChargerCommand, ChargerStatus, ChargerStatusBit, TcChargerCodec)

CODEC = TcChargerCodec()
# charger 1: 403.2 V (4032 = 0x0FC0), 12.5 A (125 = 0x007D), byte 4 = 0: charge
COMMAND_GOLDEN = bytes([0x0F, 0xC0, 0x00, 0x7D, 0x00, 0x00, 0x00, 0x00])
# charger 3: 398.7 V (3987 = 0x0F93), 9.8 A (98 = 0x0062), hardware failure (bit 0) and
# input voltage error (bit 2), temperature raw 0x41
STATUS_GOLDEN = bytes([0x0F, 0x93, 0x00, 0x62, 0b0000_0101, 0x41, 0x00, 0x00])


def test_command_golden():
    reading = CODEC.decode(0x1806E5F4, COMMAND_GOLDEN)
    assert reading == ChargerCommand(1, 403.2, 12.5, False)
    assert CODEC.encode(reading) == Frame(0x1806E5F4, COMMAND_GOLDEN, True)
    stop = COMMAND_GOLDEN[:4] + b'\x01' + COMMAND_GOLDEN[5:]
    assert CODEC.decode(0x1806E7F4, stop) == ChargerCommand(2, 403.2, 12.5, True)
    assert CODEC.decode(0x1806E8F4, COMMAND_GOLDEN[:5]).charger == 3  # DLC 5 is enough


def test_status_golden():
    reading = CODEC.decode(0x18FF50E8, STATUS_GOLDEN)
    assert reading == ChargerStatus(3, 398.7, 9.8, 0b101, 0x41)
    assert reading.active_bits == ('hardware failure', 'input (AC) voltage error')
    assert CODEC.encode(reading) == Frame(0x18FF50E8, STATUS_GOLDEN, True)
    assert CODEC.decode(0x18FF50E5, STATUS_GOLDEN).charger == 1
    assert CODEC.decode(0x18FF50E7, STATUS_GOLDEN).charger == 2
    assert CODEC.decode(0x18FF50E5, STATUS_GOLDEN[:5]).temperature_raw is None


# TC's "1430 ALG-CAN Protocol" (Lennart-O/TCCharger-voltage-current-control): Message 2,
# Vout = 3201 -> 320.1 V, Iout = 582 -> 58.2 A, "Highest Byte mark: 0: Charging, 1:
# Discharging" (bit 15 of bytes 2-3).
CHARGING_1430 = bytes([0x0C, 0x81, 0x02, 0x46, 0x00, 0x00, 0x00, 0x00])
DISCHARGING_1430 = bytes([0x0C, 0x81, 0x82, 0x46, 0x00, 0x00, 0x00, 0x00])


def test_protocol_1430_direction_bit():
    assert CODEC.decode(0x18FF50E5, CHARGING_1430) == ChargerStatus(1, 320.1, 58.2, 0, 0)
    discharging = CODEC.decode(0x18FF50E5, DISCHARGING_1430)
    assert discharging == ChargerStatus(1, 320.1, -58.2, 0, 0)  # not 3335.0 A
    assert CODEC.encode(discharging).data == DISCHARGING_1430
    # the case: 0x8064 is 10.0 A discharging, not 3286.8 A
    assert CODEC.decode(0x18FF50E5, bytes([0, 0, 0x80, 0x64, 0, 0])).output_current_a == -10.0
    db = cantools.database.load_file(str(msg_defs_dir() / 'evms3.dbc'), strict=True)
    assert db.decode_message(0x18FF50E5, DISCHARGING_1430, decode_choices=False)[
        'OutputCurrentDirection'] == 1
    assert db.decode_message(0x18FF50E5, DISCHARGING_1430)['OutputCurrent'] == \
        pytest.approx(58.2)


@pytest.mark.parametrize('bit, name, text', [
    (0, 'HARDWARE_FAILURE', 'hardware failure'),
    (1, 'OVER_TEMPERATURE', 'over-temperature shutdown'),
    (2, 'INPUT_VOLTAGE_ERROR', 'input (AC) voltage error'),
    (3, 'BATTERY_FAULT', 'battery fault / no battery'),
    (4, 'COMMUNICATION_TIMEOUT', 'communication timeout'),
    (5, None, 'bit 5'), (7, None, 'bit 7')])
def test_each_status_bit(bit, name, text):
    data = bytes([0, 0, 0, 0, 1 << bit, 0])
    reading = CODEC.decode(0x18FF50E5, data)
    assert reading.active_bits == (text,)
    if name:
        assert ChargerStatusBit[name] == 1 << bit


@pytest.mark.parametrize('frame_id, data, why', [
    (0x1806E5F4, COMMAND_GOLDEN[:4], 'DLC 4'),
    (0x1806E5F4, COMMAND_GOLDEN[:4] + b'\x02', 'byte 4 = 2'),
    (0x18FF50E5, b'', 'DLC 0'),
    (0x18FF50E5, STATUS_GOLDEN + b'\x00', 'DLC 9'),
    (0x18FF50E6, STATUS_GOLDEN, 'not a TC charger ID'),
])
def test_malformed(frame_id, data, why):
    with pytest.raises(MalformedFrameError, match=why):
        CODEC.decode(frame_id, data)


def test_encoder_refuses_what_the_wire_cannot_carry():
    with pytest.raises(EncodeRangeError, match='charger'):
        CODEC.encode(ChargerCommand(4, 100.0, 1.0, False))
    with pytest.raises(EncodeRangeError, match='target_voltage_v'):
        CODEC.encode(ChargerCommand(1, 7000.0, 1.0, False))
    with pytest.raises(EncodeRangeError, match='current_limit_a'):
        CODEC.encode(ChargerCommand(1, 100.0, 0.05, False))
    # a foreign message is refused as such (not an AttributeError on its missing .charger)
    with pytest.raises(EncodeRangeError, match='a TC charger message'):
        CODEC.encode(Frame(0x1806E5F4, COMMAND_GOLDEN, True))


def test_status_byte_and_temperature_are_checked_before_sending():
    for message, field in ((ChargerStatus(1, 100.0, 1.0, 256), 'status'),
                           (ChargerStatus(1, 100.0, 1.0, 3, 300), 'temperature_raw'),
                           (ChargerStatus(1, 100.0, 1.0, 3, 2.5), 'temperature_raw')):
        with pytest.raises(EncodeRangeError) as info:
            CODEC.encode(message)
        assert info.value.field == field and info.value.allowed == '0..255, a whole number'
    # no temperature: DLC 5 (100.0 V = 1000 = 0x03E8, 1.0 A = 10 = 0x000A, status 3)
    assert CODEC.encode(ChargerStatus(3, 100.0, 1.0, 3)) == Frame(
        0x18FF50E8, bytes([0x03, 0xE8, 0x00, 0x0A, 0x03]), True)
    assert CODEC.decode(0x18FF50E8, bytes([0x03, 0xE8, 0x00, 0x0A, 0x03])) == ChargerStatus(
        3, 100.0, 1.0, 3)


def test_dbc_agrees_with_the_golden_frames():
    db = cantools.database.load_file(str(msg_defs_dir() / 'evms3.dbc'), strict=True)
    command = db.get_message_by_frame_id(0x1806E5F4, force_extended_id=True)
    assert command.is_extended_frame and command.name == 'TC_Charger1_Command'
    assert command.decode(COMMAND_GOLDEN, decode_choices=False) == {
        'TargetVoltage': pytest.approx(403.2), 'CurrentLimit': 12.5, 'ShutdownByBms': 0}
    status = db.get_message_by_frame_id(0x18FF50E8, force_extended_id=True)
    assert status.decode(STATUS_GOLDEN, decode_choices=False) == {
        'OutputVoltage': pytest.approx(398.7), 'OutputCurrentDirection': 0,
        'OutputCurrent': pytest.approx(9.8), 'HardwareFailure': 1,
        'OverTemperature': 0, 'InputVoltageError': 1, 'BatteryFault': 0,
        'CommunicationTimeout': 0, 'Temperature': 0x41}


def test_evms3_codec_decodes_the_chargers_and_bms12_balance_request():
    evms3 = Evms3Codec(bms12_modules=2)
    assert evms3.decode(0x18FF50E8, STATUS_GOLDEN) == ChargerStatus(3, 398.7, 9.8, 5, 0x41)
    assert evms3.encode(ChargerCommand(1, 403.2, 12.5, False)).data == COMMAND_GOLDEN
    # module 1 (ID 310): balance to 4.105 V = 4105 mV = 0x1009, big-endian; 0 = off
    assert evms3.decode(310, bytes([0x10, 0x09])) == Bms12Request(1, 4105)
    assert evms3.decode(300, bytes([0x00, 0x00])) == Bms12Request(0, None)


def test_evms3_on_11_bit_ids_keeps_its_chargers_on_29_bit():
    evms3 = Evms3Codec(bms12_modules=1, extended_id=False)
    assert evms3.is_extended_id is False
    assert (30, False) in evms3.frame_ids and (300, False) in evms3.frame_ids
    assert (30, True) not in evms3.frame_ids
    assert {(0x1806E5F4, True), (0x18FF50E5, True)} <= evms3.frame_ids
    assert evms3.encode(ResetSoc()) == Frame(38, b'', False)
    assert evms3.encode(Bms12Request(0, 4000)).is_extended_id is False
    assert evms3.encode(ChargerCommand(2, 1.0, 1.0, True)).is_extended_id is True
    with pytest.raises(ValueError, match='11-bit'):
        Evms3Codec(base_id=0x7F8, extended_id=False)
    assert Evms3Codec(base_id=0x7F8).base_id == 0x7F8  # fine on 29-bit IDs
