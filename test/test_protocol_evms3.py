# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ZEVA EVMS3 + BMS12 codec against frames written by hand from doc/protocols.md section 3.

Golden bytes come from the spec tables, not from the codec or the DBC; the DBC is then
checked to read the same frames the same way, so users' CAN tools agree with the bridge.
"""
import dataclasses

import cantools
from hypothesis import given, settings, strategies as st
import pytest

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.common import msg_defs_dir
from ams_can_bridge.protocols.evms3 import (
    AcknowledgeError, BatteryCurrent, Bms12Cells, Bms12Request, Bms12Temperatures,
    ConfigReadback, ConfigReport,
    BmsCellNumbers, check_config_value, CONFIG_FIELDS, Evms3Codec, Evms3Settings,
    Evms3Error, Evms3State, Evms3Status, EVMS3_WARNINGS, PowerOff, ResetSoc,
    OtherTraffic, SetState, ZeroCurrentSensor)
from shared import EVMS3_GOLDEN_CONFIG as GOLDEN_CONFIG  # written by hand: frames below

CODEC = Evms3Codec()
SCALED = ('full_voltage_v', 'max_charge_voltage_v', 'alt_charge_voltage_v')
X = 0x80000000  # cantools keys extended frames with bit 31 set


def frame(aid, hexdata):
    return Frame(aid, bytes.fromhex(hexdata), True)


# --- status (ID 30) --------------------------------------------------------------------------
STATUS_GOLDEN = [
    # b0 0x12: state 2 (bits 2..0), error 2 (bits 7..3); 1000 x 0.1 Ah; 4000 x 0.1 V; 13.0 V;
    # b6 0xE5: headlights + isolation 101 (not measured); b7 65 - 40 = 25 degC
    ('12 03 E8 0F A0 82 E5 41', Evms3Status(
        Evms3State.RUNNING, Evms3Error.OVERCURRENT_WARNING, 100.0, 400.0, 13.0, True, None, 25)),
    # b0 0x85: state 5, error 16; 0.1 Ah; 6553.5 V; isolation 50 %; temperature raw 0 = none
    ('85 00 01 FF FF 00 32 00', Evms3Status(
        Evms3State.SETUP, Evms3Error.BMS_COMMS_ERROR, 0.1, 6553.5, 0.0, False, 50, None)),
    # isolation 0 with headlights, temperature raw 1 = -39 degC, raw 255 aux = 25.5 V
    ('3B 30 39 01 02 FF 80 01', Evms3Status(
        Evms3State.CHARGING, Evms3Error.BMS_ENDED_CHARGE, 1234.5, 25.8, 25.5, True, 0, -39)),
]


@pytest.mark.parametrize('hexdata,reading', STATUS_GOLDEN)
def test_status_golden_both_ways(hexdata, reading):
    assert CODEC.decode(30, bytes.fromhex(hexdata)) == reading
    assert CODEC.encode(reading) == frame(30, hexdata)


@pytest.mark.parametrize('state', range(6))
def test_every_state(state):
    reading = CODEC.decode(30, bytes([state, 0, 0, 0, 0, 0, 100, 0]))
    assert reading.state == state and reading.state is Evms3State(state)
    assert reading.error is Evms3Error.NONE


@pytest.mark.parametrize('error', range(17))
def test_every_error_code(error):
    reading = CODEC.decode(30, bytes([error << 3 | 2, 0, 0, 0, 0, 0, 100, 0]))
    assert reading.error is Evms3Error(error)
    assert reading.state is Evms3State.RUNNING


def test_error_names_and_warnings_follow_the_vendor_table():
    assert [e.name for e in Evms3Error] == [
        'NONE', 'CORRUPT_SETTINGS', 'OVERCURRENT_WARNING', 'OVERCURRENT_SHUTDOWN',
        'LOW_CELL_WARNING', 'BMS_SHUTDOWN', 'HIGH_CELL_WARNING', 'BMS_ENDED_CHARGE',
        'BMS_OVER_TEMP', 'BMS_UNDER_TEMP', 'LOW_SOC_WARNING', 'OVERTEMPERATURE',
        'ISOLATION_ERROR', 'LOW_12V', 'PRECHARGE_FAILED', 'CONTACTOR_SWITCH_ERROR',
        'BMS_COMMS_ERROR']
    assert EVMS3_WARNINGS == {2, 4, 6, 10}
    assert [s.name for s in Evms3State] == [
        'IDLE', 'PRECHARGING', 'RUNNING', 'CHARGING', 'STOPPED', 'SETUP']


@pytest.mark.parametrize('aid,data,reason', [
    (30, bytes([6, 0, 0, 0, 0, 0, 0, 0]), 'unknown state 6 (0..5)'),
    (30, bytes([7, 0, 0, 0, 0, 0, 0, 0]), 'unknown state 7 (0..5)'),
    (30, bytes([17 << 3, 0, 0, 0, 0, 0, 0, 0]), 'unknown error code 17 (0..16)'),
    (30, bytes([31 << 3 | 2, 0, 0, 0, 0, 0, 0, 0]), 'unknown error code 31 (0..16)'),
    (30, bytes([2, 0, 0, 0, 0, 0, 102, 0]), 'isolation 102 % (0..100, 101 = n/a)'),
    (30, bytes(7), 'DLC 7, expected 8'),
    (30, b'', 'DLC 0, expected 8'),
    (31, b'\x02', 'set state 2, expected 0 or 1'),
    (31, b'', 'DLC 0, expected 1 or 2'),
    (31, bytes(3), 'DLC 3, expected 1 or 2'),
    (31, b'\x00\x05', 'set state 0 with a gauge value, expected 1..3'),
    (31, b'\x04\x05', 'set state 4 with a gauge value, expected 1..3'),
    (32, bytes(8), 'pack_capacity_ah raw 0 outside 1..250'),
    (32, bytes(7), 'DLC 7, expected 8'),
    (33, bytes([1, 0, 0, 0, 0, 251, 0, 0]), 'bms_min_cell_v raw 251 outside 0..250'),
    (33, bytes([1, 0, 0, 0, 0, 0, 0, 253]), 'balance voltage raw 253 outside 0..252'),
    (34, bytes([51, 0, 0, 0, 0, 0, 0, 1]), 'bms_hysteresis_v raw 51 outside 0..50'),
    (34, bytes([0, 0, 0, 0, 0, 0, 0, 0]), 'sleep_delay_min raw 0 outside 1..6'),
    (35, bytes([0, 0, 0, 1, 2, 0, 0, 0]), 'enable_precharge raw 2, expected 0 or 1'),
    (35, bytes([0, 0, 0, 21, 0, 0, 0, 0]), 'parallel_strings raw 21 outside 1..20'),
    (35, bytes(7), 'DLC 7, expected 8'),
    # bytes 6-7 are settings 30-31 (Common.h): reverse current display 0..1, brightness 0..10
    (35, bytes([0, 0, 0, 1, 0, 0, 0, 0])[:6], 'DLC 6, expected 8'),
    (35, bytes([0, 0, 0, 1, 0, 0, 2, 0]), 'reverse_current_display raw 2, expected 0 or 1'),
    (35, bytes([0, 0, 0, 1, 0, 0, 0, 11]), 'night_brightness raw 11 outside 0..10'),
    (32, bytes([1, 0, 5, 1, 1, 0, 17, 0]), 'min_aux_voltage_v raw 17 outside 8..16'),
    (36, bytes(7), 'DLC 7, expected 8'),
    # cells per module 0 or 4..12: the firmware's arrays hold 12 (13..15 would overrun them)
    (36, bytes.fromhex('0C 00 00 00 00 00 00 D0'), 'module 15: 13 cells (0 or 4..12)'),
    (56, bytes.fromhex('3C 00 00 00 00 00 00 00'), 'module 1: 3 cells (0 or 4..12)'),
    (37, b'\x11', 'unknown error code 17 (0..16)'),
    (37, b'', 'DLC 0, expected 1'),
    (39, b'\x00', 'DLC 1, expected 0'),
    (40, b'\x80\x00', 'DLC 2, expected 3'),
    (40, b'\x80\x00\x00\x00', 'DLC 4, expected 3'),
    (41, b'\x00', 'DLC 1, expected 0'),
    (300, b'\x0e', 'DLC 1, expected 2'),
    (301, bytes(7), 'DLC 7, expected 8'),
    (454, bytes(5), 'DLC 5, expected 2 or 8'),
    (29, bytes(8), 'not an EVMS3/BMS12 ID of this codec'),
    (305, bytes(8), 'not an EVMS3/BMS12 ID of this codec'),
])
def test_malformed(aid, data, reason):
    with pytest.raises(MalformedFrameError) as info:
        CODEC.decode(aid, data)
    assert info.value.arbitration_id == aid
    assert info.value.reason == reason


# --- commands ---------------------------------------------------------------------------------
@pytest.mark.parametrize('msg,aid,hexdata', [
    (SetState(True), 31, '01'),
    (SetState(False), 31, '00'),
    (AcknowledgeError(Evms3Error.BMS_ENDED_CHARGE), 37, '07'),
    (AcknowledgeError(Evms3Error.BMS_COMMS_ERROR), 37, '10'),
    (ResetSoc(), 38, ''),
    (PowerOff(), 39, ''),
    (ZeroCurrentSensor(), 41, ''),
    # module 2n in the low nibble of byte n, 2n+1 in the high nibble
    (BmsCellNumbers((12, 8, 4, 5) + (0,) * 11 + (12,)), 36, '8C 54 00 00 00 00 00 C0'),
    (BmsCellNumbers((4, 5, 6, 7, 8, 9, 10, 11, 12) + (0,) * 7), 36, '54 76 98 BA 0C 00 00 00'),
    # 24 bit BE, + 8388608, mA, positive = discharge
    (BatteryCurrent(10.0), 40, '80 27 10'),
    (BatteryCurrent(-20.5), 40, '7F AF EC'),
    (BatteryCurrent(0.0), 40, '80 00 00'),
    (BatteryCurrent(-8388.608), 40, '00 00 00'),
    (BatteryCurrent(8388.607), 40, 'FF FF FF'),
    (BatteryCurrent(0.001), 40, '80 00 01'),
])
def test_command_golden_both_ways(msg, aid, hexdata):
    assert CODEC.encode(msg) == frame(aid, hexdata)
    assert CODEC.decode(aid, bytes.fromhex(hexdata)) == msg


def test_reset_soc_ignores_data_as_the_vendor_says():
    assert CODEC.decode(38, b'\x01\x02') == ResetSoc()


@pytest.mark.parametrize('msg,field', [
    (BatteryCurrent(8388.608), 'current_a'),
    (BatteryCurrent(-8388.609), 'current_a'),
    (BatteryCurrent(1.0005), 'current_a'),
    (BatteryCurrent(float('nan')), 'current_a'),
    (AcknowledgeError(17), 'error'),
    (BmsCellNumbers((16,) + (0,) * 15), 'cells_per_module[0]'),
    (BmsCellNumbers((1,) * 15), 'cells_per_module'),
    # 0 or 4..12 cells a module (firmware arrays hold 12; the Monitor offers 4..12)
    (BmsCellNumbers((12,) * 15 + (13,)), 'cells_per_module[15]'),
    (BmsCellNumbers((0, 3) + (0,) * 14), 'cells_per_module[1]'),
    (Bms12Temperatures(0, (25, -40)), 'temperatures_c[1]'),  # raw 0 means no sensor
    (Bms12Request(16, 3600), 'module'),
    (Bms12Request(0, 65536), 'balance_mv'),
    (Bms12Cells(0, 2, (3.3,) * 4), 'first_cell'),
    (Bms12Cells(0, 0, (3.3, 3.3, 3.3, 65.536)), 'voltages_v[3]'),
    (Bms12Cells(0, 0, (3.3, 3.3, 3.3005, 3.3)), 'voltages_v[2]'),
    (Bms12Temperatures(0, (25, 216)), 'temperatures_c[1]'),
    (Evms3Status(6, 0, 0, 0, 0, False, None, None), 'state'),
    (Evms3Status(2, 17, 0, 0, 0, False, None, None), 'error'),
    (Evms3Status(2, 0, 6553.6, 0, 0, False, None, None), 'amp_hours_ah'),
    (Evms3Status(2, 0, 0, 0, 0, False, 101, None), 'isolation_pct'),
    (Evms3Status(2, 0, 0, 0, 0, False, None, -40), 'temperature_c'),
])
def test_encode_refuses_out_of_range(msg, field):
    with pytest.raises(EncodeRangeError) as info:
        CODEC.encode(msg)
    assert info.value.field == field


# --- BMS12 -----------------------------------------------------------------------------------
@pytest.mark.parametrize('msg,aid,hexdata', [
    (Bms12Request(3, 3600), 330, '0E 10'),
    (Bms12Request(0, None), 300, '00 00'),
    (Bms12Cells(2, 4, (3.301, 3.302, 0.0, 10.0)), 322, '0C E5 0C E6 00 00 27 10'),
    (Bms12Cells(0, 0, (4.2, 3.0, 2.5, 3.65)), 301, '10 68 0B B8 09 C4 0E 42'),
    (Bms12Cells(15, 8, (1.0, 1.0, 1.0, 1.0)), 453, '03 E8 03 E8 03 E8 03 E8'),
    # raw 0 = no sensor (BMS12 firmware LineariseTemp); raw 1 = -39 degC
    (Bms12Temperatures(15, (25, None)), 454, '41 00 00 00 00 00 00 00'),
    (Bms12Temperatures(0, (None, -39)), 304, '00 01 00 00 00 00 00 00'),
])
def test_bms12_golden_both_ways(msg, aid, hexdata):
    assert CODEC.encode(msg) == frame(aid, hexdata)
    assert CODEC.decode(aid, bytes.fromhex(hexdata)) == msg


def test_bms12_temperatures_with_the_pdf_dlc_2():
    assert CODEC.decode(314, b'\x3c\x28') == Bms12Temperatures(1, (20, 0))
    assert CODEC.decode(314, b'\x00\x00') == Bms12Temperatures(1, (None, None))


@pytest.mark.parametrize('hexdata,reading', [
    # EVMS_Monitor3.c TransmitGaugeState: DLC 2, byte 0 = CORE_SETUP_EDIT_FUEL_GAUGE (2) or
    # CORE_SETUP_EDIT_TEMP_GAUGE (3) or CORE_SETUP_STATE (1), byte 1 = the setting's value
    ('02 50', SetState(True, 2, 80)),
    ('03 14', SetState(True, 3, 20)),
    ('01 FB', SetState(True, 1, 251)),
])
def test_monitor_gauge_editing_on_id_31_is_normal(hexdata, reading):
    assert CODEC.decode(31, bytes.fromhex(hexdata)) == reading
    assert CODEC.encode(reading) == frame(31, hexdata)


@pytest.mark.parametrize('hexdata', [
    '00',  # EVMS_Monitor3.c SEND_ENTER_SETUP: ID 52 (MC_RECEIVE_SETTINGS_ID), DLC 1, 0
    # TransmitSettings: the motor controller settings, DLC 8 (min batt 100 V, max motor
    # 150 V, 80 % / 60 %, ramp 2 + speed 1 << 4, throttle type 1, idle 0 V, idle 0 A): byte 1
    # (150) is no SoC warning % and byte 6 (0) no minimum aux voltage
    '64 96 50 3C 12 01 00 00',
])
def test_monitor_motor_controller_settings_on_id_52_are_not_malformed(hexdata):
    reading = CODEC.decode(52, bytes.fromhex(hexdata))
    assert isinstance(reading, OtherTraffic) and reading.arbitration_id == 52


def test_ids_base_and_module_count():
    codec = Evms3Codec(base_id=1000, bms12_modules=2)
    assert codec.is_extended_id is True
    chargers = {0x1806E5F4, 0x1806E7F4, 0x1806E8F4, 0x18FF50E5, 0x18FF50E7, 0x18FF50E8}
    readback = set(range(52, 57))  # fixed IDs in ZEVA's firmware, whatever the base
    assert codec.arbitration_ids == frozenset(
        list(range(1000, 1012)) + list(range(300, 305)) + list(range(310, 315))) | chargers \
        | readback
    assert codec.decode(1000, bytes([2, 0, 0, 0, 0, 0, 100, 0])).state is Evms3State.RUNNING
    assert codec.encode(ResetSoc()) == Frame(1006 + 2, b'', True)
    with pytest.raises(MalformedFrameError):
        codec.decode(320, bytes(8))  # module 2 not configured
    with pytest.raises(ValueError):
        Evms3Codec(base_id=295)  # 295..306 would overlap BMS12 module 0


# --- configuration (IDs 32..35) ----------------------------------------------------------------
GOLDEN_CONFIG_FRAMES = [
    frame(32, '14 14 C8 1E 32 3C 0B 32'),  # 100/5, 20, 400/2, 300/10, 500/10, 60, 11, 50
    frame(33, '02 5A 0A 50 14 82 A5 96'),  # (2.80-1.50)/0.01=130, (3.65-2)/0.01=165, 150
    # 300 V = 0x12C: low byte 2C, 9th bit -> bit 7 of the current byte (30 | 0x80 = 9E)
    frame(34, '05 28 5F 2C 9E FA 0A 03'),
    # settings 24..31: MPI 1, MPO1 2, MPO2 6, 2 strings, precharge, not stationary,
    # reverse current display 1, night brightness 7 (Common.h settings order)
    frame(35, '01 02 06 02 01 00 01 07'),
]


def test_config_golden():
    assert CODEC.config_frames(GOLDEN_CONFIG) == GOLDEN_CONFIG_FRAMES
    parts = [CODEC.decode(f.arbitration_id, f.data) for f in GOLDEN_CONFIG_FRAMES]
    assert [p.part for p in parts] == [1, 2, 3, 4]
    assert Evms3Settings.from_parts(parts) == GOLDEN_CONFIG
    assert CODEC.encode(parts[2]) == GOLDEN_CONFIG_FRAMES[2]


@pytest.mark.parametrize('changes,byte3,byte4,byte5,byte6', [
    (dict(max_charge_voltage_v=511, max_charge_current_a=127,
          alt_charge_voltage_v=256, alt_charge_current_a=0), 0xFF, 0xFF, 0x00, 0x80),
    (dict(max_charge_voltage_v=255, max_charge_current_a=0,
          alt_charge_voltage_v=0, alt_charge_current_a=127), 0xFF, 0x00, 0x00, 0x7F),
])
def test_config_ninth_bit_of_charge_voltages(changes, byte3, byte4, byte5, byte6):
    cfg = dataclasses.replace(GOLDEN_CONFIG, **changes)
    data = CODEC.config_frames(cfg)[2].data
    assert data[3:7] == bytes([byte3, byte4, byte5, byte6])
    assert CODEC.decode(34, data).values.items() >= changes.items()


@pytest.mark.parametrize('mode,balance_v,raw', [
    ('dynamic', None, 251), ('off', None, 252), ('dynamic', 3.4, 251),
    ('static', 2.0, 0), ('static', 4.5, 250), ('static', 3.0, 100), ('static', 3, 100),
])
def test_config_balance_modes(mode, balance_v, raw):
    cfg = dataclasses.replace(GOLDEN_CONFIG, balance_mode=mode, balance_v=balance_v)
    data = CODEC.config_frames(cfg)[1].data
    assert data[7] == raw
    part = CODEC.decode(33, data)
    assert part.values['balance_mode'] == mode
    assert part.values['balance_v'] == (float(balance_v) if mode == 'static' else None)


def test_config_4_bytes_6_and_7_are_settings_30_and_31():
    assert CODEC.decode(35, bytes([3, 6, 0, 20, 0, 1, 0, 10])).values == dict(
        mpi_function=3, mpo1_function=6, mpo2_function=0, parallel_strings=20,
        enable_precharge=False, stationary_mode=True, reverse_current_display=False,
        night_brightness=10)


def test_sentinels_are_documented_values_and_shown_as_off():
    # EVMS3 firmware: CURRENT_WARNING/TRIP 121 = off (x 10 A), OVER_TEMP 151 = off,
    # BMS_MIN_TEMP raw 0 (-40) and BMS_MAX_TEMP raw 141 (101) = off, CAN power-down 6 = never
    cfg = dataclasses.replace(GOLDEN_CONFIG, warn_current_a=1210, trip_current_a=1210,
                              temp_warning_c=151, bms_min_temp_c=-40, bms_max_temp_c=101,
                              sleep_delay_min=6)
    frames = CODEC.config_frames(cfg)
    assert frames[0].data == bytes.fromhex('14 14 C8 79 79 97 0B 32')
    assert frames[2].data[1:3] == bytes([0, 141]) and frames[2].data[7] == 6
    readback = ConfigReadback.join(
        [ConfigReport(52 + i, CODEC.decode(f.arbitration_id, f.data).values)
         for i, f in enumerate(frames)] + [ConfigReport(56, {'cells_per_module': (12,) * 16})])
    text = readback.summary()
    for name in ('warn_current_a off', 'trip_current_a off', 'temp_warning_c off',
                 'bms_min_temp_c off', 'bms_max_temp_c off', 'sleep_delay_min never'):
        assert name in text, text
    by_name = {f.name: f for f in CONFIG_FIELDS}
    assert '1210 = off' in by_name['warn_current_a'].description
    assert '6 = never' in by_name['sleep_delay_min'].description
    assert '-40 = off' in by_name['bms_min_temp_c'].description
    assert 'sleep_delay_min never' not in ConfigReadback.join(
        [ConfigReport(52 + i, CODEC.decode(f.arbitration_id, f.data).values)
         for i, f in enumerate(CODEC.config_frames(GOLDEN_CONFIG))]
        + [ConfigReport(56, {'cells_per_module': (12,) * 16})]).summary()


def test_voltage_multiplier_2_scales_full_and_charge_voltages():
    # Common.h PACK_VOLTAGE_MULTIPLIER 2: full voltage raw x 2 V x 2, charger voltage raw x 2
    # (EVMS3 firmware: targetVoltage *= PACK_VOLTAGE_MULTIPLIER; Monitor: value *= it)
    codec = Evms3Codec(voltage_multiplier=2)
    cfg = dataclasses.replace(GOLDEN_CONFIG, full_voltage_v=800, max_charge_voltage_v=600,
                              alt_charge_voltage_v=1022)
    frames = codec.config_frames(cfg)
    assert frames[0].data[2] == 200  # 800 V / 4 V per step
    # 600 V / 2 = 300 = 0x12C; 1022 / 2 = 511 = 0x1FF
    assert frames[2].data[3:7] == bytes([0x2C, 0x9E, 0xFF, 0x8A])
    assert Evms3Settings.from_parts(codec.decode(f.arbitration_id, f.data) for f in frames) == cfg
    with pytest.raises(EncodeRangeError) as info:
        codec.config_frames(dataclasses.replace(cfg, full_voltage_v=802))  # off the 4 V step
    assert info.value.field == 'full_voltage_v' and '20..1004' in str(info.value)
    with pytest.raises(EncodeRangeError):
        CODEC.config_frames(cfg)  # 800 V full is beyond a x1 build
    with pytest.raises(ValueError):
        Evms3Codec(voltage_multiplier=3)


def test_integers_and_floats_mean_the_same_value():
    a = dataclasses.replace(GOLDEN_CONFIG, bms_min_cell_v=3, pack_capacity_ah=100.0,
                            bms_hysteresis_v=0, full_voltage_v=400.0)
    b = dataclasses.replace(GOLDEN_CONFIG, bms_min_cell_v=3.0, pack_capacity_ah=100,
                            bms_hysteresis_v=0.0, full_voltage_v=400)
    assert CODEC.config_frames(a) == CODEC.config_frames(b)


# Ranges written by hand from the spec table (physical = raw x scale + offset).
EXPECTED_RANGES = {
    'pack_capacity_ah': (5, 1250, 5), 'soc_warning_pct': (0, 99, 1),
    'full_voltage_v': (10, 502, 2), 'warn_current_a': (10, 1210, 10),
    'trip_current_a': (10, 1210, 10), 'temp_warning_c': (0, 151, 1),
    'min_aux_voltage_v': (8, 16, 1), 'night_brightness': (0, 10, 1),
    'min_isolation_pct': (0, 99, 1), 'tacho_ppr': (1, 6, 1),
    'fuel_gauge_full_pct': (0, 100, 1), 'fuel_gauge_empty_pct': (0, 100, 1),
    'temp_gauge_hot_pct': (0, 100, 1), 'temp_gauge_cold_pct': (0, 100, 1),
    'bms_min_cell_v': (1.5, 4.0, 0.01), 'bms_max_cell_v': (2.0, 4.5, 0.01),
    'balance_v': (2.0, 4.5, 0.01), 'bms_hysteresis_v': (0, 0.5, 0.01),
    'bms_min_temp_c': (-40, 101, 1), 'bms_max_temp_c': (-40, 101, 1),
    'max_charge_voltage_v': (0, 511, 1), 'max_charge_current_a': (0, 127, 1),
    'alt_charge_voltage_v': (0, 511, 1), 'alt_charge_current_a': (0, 127, 1),
    'sleep_delay_min': (1, 6, 1), 'mpi_function': (0, 3, 1), 'mpo1_function': (0, 6, 1),
    'mpo2_function': (0, 6, 1), 'parallel_strings': (1, 20, 1),
}


def test_config_fields_cover_the_config_and_the_spec_ranges():
    names = [f.name for f in CONFIG_FIELDS]
    assert names == [f.name for f in dataclasses.fields(Evms3Settings)] + ['cells_per_module']
    for spec in CONFIG_FIELDS:
        if spec.name in EXPECTED_RANGES:
            low, high, step = EXPECTED_RANGES[spec.name]
            if spec.name in SCALED:  # declared for both builds (voltage_multiplier 1 or 2)
                high *= 2
            assert (spec.low, spec.high, spec.step) == pytest.approx((low, high, step)), \
                spec.name
            assert spec.description and spec.type in (int, float)
    by_name = {f.name: f for f in CONFIG_FIELDS}
    assert by_name['balance_mode'].choices == ('static', 'dynamic', 'off')
    assert by_name['enable_precharge'].type is bool
    cells = by_name['cells_per_module']
    assert (cells.type, cells.length, cells.low, cells.high) == ('int[]', 16, 0, 12)


def _bad_values(low, high, step):
    yield low - step
    yield high + step
    yield low + step / 2  # off the step grid
    if step == 0.01:
        yield low + 1.505


@pytest.mark.parametrize('name', sorted(EXPECTED_RANGES))
def test_config_refuses_out_of_range_and_off_step(name):
    low, high, step = EXPECTED_RANGES[name]
    for bad in _bad_values(low, high, step):
        cfg = dataclasses.replace(GOLDEN_CONFIG, **{name: bad})
        with pytest.raises(EncodeRangeError) as info:
            CODEC.config_frames(cfg)
        assert info.value.field == name
        text = str(info.value)
        assert name in text and f'{low:g}..{high:g}' in text and repr(bad) in text
    for good in (low, high):
        check_config_value(name, good)


@pytest.mark.parametrize('name,value', [
    ('bms_min_cell_v', 3.005), ('enable_precharge', 'yes'), ('enable_precharge', 2),
    ('stationary_mode', None), ('balance_mode', 'auto'), ('pack_capacity_ah', True),
    ('pack_capacity_ah', '100'), ('pack_capacity_ah', None), ('balance_v', float('nan')),
    ('cells_per_module', [12] * 15), ('cells_per_module', 'abc'),
])
def test_config_refuses_wrong_kinds(name, value):
    with pytest.raises(EncodeRangeError) as info:
        check_config_value(name, value)
    assert info.value.field == name


@pytest.mark.parametrize('bad', [13, 15, 16, 1, 3])
def test_cells_per_module_names_the_bad_entry(bad):
    with pytest.raises(EncodeRangeError) as info:
        check_config_value('cells_per_module', [12, 12, 12, bad] + [0] * 12)
    assert info.value.field == 'cells_per_module[3]'
    assert check_config_value('cells_per_module', [0, 4, 12] + [0] * 13)[:3] == (0, 4, 12)


def test_static_balance_needs_balance_v_and_missing_values_are_named():
    with pytest.raises(EncodeRangeError) as info:
        CODEC.config_frames(dataclasses.replace(GOLDEN_CONFIG, balance_v=None))
    assert info.value.field == 'balance_v'
    values = dataclasses.asdict(GOLDEN_CONFIG)
    del values['tacho_ppr'], values['stationary_mode']
    with pytest.raises(EncodeRangeError) as info:
        Evms3Settings.from_mapping(values)
    assert 'tacho_ppr' in str(info.value) and 'stationary_mode' in str(info.value)


# --- property tests -----------------------------------------------------------------------------
@settings(max_examples=200, deadline=None)
@given(st.sampled_from(sorted(CODEC.arbitration_ids)), st.binary(max_size=8))
def test_any_frame_decodes_or_is_malformed(aid, data):
    try:
        reading = CODEC.decode(aid, data)
    except MalformedFrameError:
        return
    if isinstance(reading, OtherTraffic):  # a Monitor's / motor controller's frame: ignored
        assert aid in (52, 53)
        return
    again = CODEC.encode(reading)  # whatever decodes must encode back to the same reading
    assert again.arbitration_id == aid and CODEC.decode(aid, again.data) == reading


def _value(spec):
    if spec.type is bool:
        return st.booleans()
    n = int(round((spec.high - spec.low) / spec.step))
    return st.integers(0, n).map(
        lambda k: spec.low + k * spec.step if spec.type is int
        else round(spec.low + k * spec.step, 2))


@st.composite
def configs(draw):
    values = {}
    for spec in CONFIG_FIELDS:
        if spec.name in ('cells_per_module', 'balance_mode', 'balance_v'):
            continue
        if spec.name in SCALED:
            spec = dataclasses.replace(spec, high=EXPECTED_RANGES[spec.name][1])
        values[spec.name] = draw(_value(spec))
    values['balance_mode'] = draw(st.sampled_from(('static', 'dynamic', 'off')))
    by_name = {f.name: f for f in CONFIG_FIELDS}
    values['balance_v'] = (draw(_value(by_name['balance_v']))
                           if values['balance_mode'] == 'static' else None)
    return Evms3Settings(**values)


@settings(max_examples=150, deadline=None)
@given(configs())
def test_config_round_trip(cfg):
    frames = CODEC.config_frames(cfg)
    assert [f.arbitration_id for f in frames] == [32, 33, 34, 35]
    assert all(f.is_extended_id and len(f.data) == 8 for f in frames)
    assert Evms3Settings.from_parts(CODEC.decode(f.arbitration_id, f.data) for f in frames) == cfg


# --- the DBC reads the same frames the same way -------------------------------------------------
@pytest.fixture(scope='module')
def dbc():
    return cantools.database.load_file(str(msg_defs_dir() / 'evms3.dbc'), strict=True)


def test_dbc_agrees_on_status_current_and_bms12(dbc):
    data = bytes.fromhex(STATUS_GOLDEN[2][0])
    decoded = dbc.decode_message(30 | X, data, decode_choices=False)
    reading = CODEC.decode(30, data)
    assert decoded['State'] == reading.state and decoded['ErrorCode'] == reading.error
    assert decoded['AmpHoursRemaining'] == pytest.approx(reading.amp_hours_ah)
    assert decoded['BatteryVoltage'] == pytest.approx(reading.pack_voltage_v)
    assert decoded['AuxVoltage'] == pytest.approx(reading.aux_voltage_v)
    assert decoded['IsolationIntegrity'] == reading.isolation_pct
    assert decoded['Headlights'] == reading.headlights
    assert decoded['Temperature'] == reading.temperature_c
    assert dbc.decode_message(40 | X, bytes.fromhex('7F AF EC'))['BatteryCurrent'] == \
        pytest.approx(-20.5)
    cells = dbc.decode_message(322 | X, bytes.fromhex('0C E5 0C E6 00 00 27 10'))
    assert [cells[f'Cell{i}'] for i in (5, 6, 7, 8)] == pytest.approx([3.301, 3.302, 0, 10.0])
    assert dbc.get_message_by_frame_id(454 | X).name == 'BMS12_M15_Temperatures'
    numbers = dbc.decode_message(36 | X, bytes.fromhex('8C 43 00 00 00 00 00 F0'))
    assert [numbers[f'Module{m}Cells'] for m in (0, 1, 2, 3, 15)] == [12, 8, 3, 4, 15]


def test_dbc_agrees_on_the_configuration(dbc):
    got = {}
    for f in GOLDEN_CONFIG_FRAMES:
        got.update(dbc.decode_message(f.arbitration_id | X, f.data, decode_choices=False))
    cfg = GOLDEN_CONFIG
    assert got['PackCapacity'] == cfg.pack_capacity_ah
    assert got['FullVoltage'] == cfg.full_voltage_v
    assert got['WarnCurrent'] == cfg.warn_current_a
    assert got['BmsMinVoltage'] == pytest.approx(cfg.bms_min_cell_v)
    assert got['BmsMaxVoltage'] == pytest.approx(cfg.bms_max_cell_v)
    assert got['BalanceVoltage'] == pytest.approx(cfg.balance_v)
    assert got['BmsHysteresis'] == pytest.approx(cfg.bms_hysteresis_v)
    assert got['BmsMaxTemp'] == cfg.bms_max_temp_c
    assert got['MaxChargeVoltageLow'] + got['MaxChargeVoltageBit8'] == cfg.max_charge_voltage_v
    assert got['MaxChargeCurrent'] == cfg.max_charge_current_a
    assert got['AltChargeVoltageLow'] + got['AltChargeVoltageBit8'] == cfg.alt_charge_voltage_v
    assert got['ParallelStrings'] == cfg.parallel_strings
    assert got['EnablePrecharge'] == 1
    assert got['ReverseCurrentDisplay'] == 1 and got['NightBrightness'] == 7  # settings 30, 31
    temps = dbc.decode_message(454 | X, bytes.fromhex('41 00 00 00 00 00 00 00'))
    assert temps['Temperature1'] == 25 and str(temps['Temperature2']) == 'No sensor'
