# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
BMS16 standard form (doc/protocols.md section 6): codec and device on hand-written frames.

Every golden frame below is written byte by byte from ZEVA's EVMS Monitor firmware
(soyachips/ZEVA_EVMS_Monitor_v3_FZR250, EVMS_Monitor3.c and Common.h): the status layout and
the marker in ProcessCanRX, the cells as BMS12 replies 1 and 2 of modules 0 and 1 in
RenderBMSDetails, the settings in TransmitSettings / bms16maximums / RenderSettings.
"""
import math

from hypothesis import given, settings, strategies as st
import pytest

from ams_can_bridge import registry
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.base import device_params, Level, PowerSupplyHealth
from ams_can_bridge.errors import (
    ConfigError, EncodeRangeError, MalformedFrameError, RefusedCommand)
from ams_can_bridge.protocols.bms16_std import (
    Bms16StdCodec, Bms16StdStatus, check_config_value, config_from_mapping)
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import (
    AcknowledgeError, BatteryCurrent, Bms12Cells, Evms3Error, Evms3State, PowerOff, ResetSoc)
from helpers import assert_decodes_or_malformed, Clock
from shared import (BMS16_STD_CONFIG as CONFIG, BMS16_STD_EVMS3_STATUS as EVMS3_STATUS,
                    BMS16_STD_STATUS as STATUS, BMS16_STD_WRITE as GOLDEN_WRITE)

# BMS12 reply 1 of module 0 (ID 301): cells 1..4 = 3.300, 3.301, 3.302, 3.303 V (uint16 BE mV)
CELLS_301 = bytes.fromhex('0C E4 0C E5 0C E6 0C E7')
# reply 2 of module 1 (ID 312): cells 13..16 = 3.310, 3.311, 3.312, 3.313 V
CELLS_312 = bytes.fromhex('0C EE 0C EF 0C F0 0C F1')
# ID 40: 24-bit BE mA + 8388608 (0x800000): 0x802710 = +10.000 A (discharge)
CURRENT_40 = bytes.fromhex('80 27 10')


def std_device(clock=None, **params):
    cls = registry.device_class('bms16', 'standard')
    values = {spec.key: spec.default for spec in device_params(cls)}
    values.update(params)
    return cls('bms16', values, clock or Clock())


# --- codec --------------------------------------------------------------------------------
def test_status_with_the_bms16_marker_decodes():
    status = Bms16StdCodec().decode(30, STATUS)
    assert status == Bms16StdStatus(Evms3State.RUNNING, Evms3Error.LOW_SOC_WARNING, 123.4,
                                    52.8, 25)


def test_status_without_the_marker_is_not_a_bms16():
    with pytest.raises(MalformedFrameError, match='byte 5 = 123, not the BMS16 marker 255'):
        Bms16StdCodec().decode(30, EVMS3_STATUS)


def test_status_temperature_raw_zero_is_no_sensor_and_bad_codes_are_malformed():
    codec = Bms16StdCodec()
    assert codec.decode(30, bytes.fromhex('00 00 00 00 00 FF 00 00')).temperature_c is None
    for data in (bytes.fromhex('06 00 00 00 00 FF 00 41'),   # state 6: none such
                 bytes.fromhex('88 00 00 00 00 FF 00 41'),   # error 17: none such
                 bytes.fromhex('00 00 00 00 00 FF 00')):     # DLC 7
        with pytest.raises(MalformedFrameError):
            codec.decode(30, data)


def test_cells_and_current():
    codec = Bms16StdCodec()
    assert codec.decode(301, CELLS_301) == Bms12Cells(0, 0, (3.3, 3.301, 3.302, 3.303))
    assert codec.decode(312, CELLS_312) == Bms12Cells(1, 4, (3.31, 3.311, 3.312, 3.313))
    assert codec.decode(40, CURRENT_40) == BatteryCurrent(10.0)
    assert codec.decode(40, bytes.fromhex('7F D8 F0')) == BatteryCurrent(-10.0)
    assert codec.arbitration_ids == {30, 40, 301, 302, 311, 312}


def test_commands_are_ids_37_38_39_extended():
    codec = Bms16StdCodec()
    assert codec.encode(AcknowledgeError(Evms3Error.LOW_SOC_WARNING)) == Frame(37, b'\x0a', True)
    assert codec.encode(ResetSoc()) == Frame(38, b'', True)
    assert codec.encode(PowerOff()) == Frame(39, b'', True)
    assert Bms16StdCodec(100).encode(PowerOff()) == Frame(109, b'', True)


def test_config_frames_are_the_monitors_settings_with_bms16_meanings():
    values = {k: check_config_value(k, v) for k, v in CONFIG.items()}
    frames = Bms16StdCodec().config_frames(config_from_mapping(values))
    assert [(f.arbitration_id, f.data) for f in frames] == GOLDEN_WRITE
    assert all(f.is_extended_id for f in frames)


@pytest.mark.parametrize('mode, raw', [('dynamic', 0xFB), ('off', 0xFC)])
def test_balance_dynamic_and_off(mode, raw):
    values = {k: check_config_value(k, v) for k, v in CONFIG.items() if k != 'balance_v'}
    values['balance_mode'] = mode
    frames = Bms16StdCodec().config_frames(config_from_mapping(values))
    assert frames[2].arbitration_id == 33 and frames[2].data[7] == raw


@pytest.mark.parametrize('name, value', [
    ('cells', 7), ('cells', 17),                     # Monitor: 8..16 for a BMS16
    ('full_voltage_v', 71), ('full_voltage_v', 4),   # bms16maximums 70, minimums 5
    ('pack_capacity_ah', 1255), ('pack_capacity_ah', 7),  # 5..1250 in steps of 5
    ('shunt_size_a', 250), ('min_cell_v', 4.01), ('warn_current_a', 1220),
    ('max_charge_voltage_v', 71), ('max_charge_current_a', 128), ('night_brightness', 11),
    ('balance_mode', 'fast'), ('stationary_mode', 2)])
def test_config_values_outside_the_monitors_ranges_are_refused(name, value):
    with pytest.raises(EncodeRangeError):
        check_config_value(name, value)


# --- device -------------------------------------------------------------------------------
def test_device_reports_status_cells_and_current():
    clock = Clock()
    device = std_device(clock, **{'config.pack_capacity_ah': 200, 'config.cells': 16})
    assert device.handle_frame(30, STATUS, 1.0)
    for can_id, data in ((301, CELLS_301), (312, CELLS_312), (40, CURRENT_40)):
        assert not device.handle_frame(can_id, data, 1.0)
    report = device.battery_report()
    assert report.present and report.voltage == 52.8 and report.charge == 123.4
    assert report.percentage == pytest.approx(123.4 / 200)
    assert report.current == -10.0          # ROS: negative while discharging
    assert report.temperature == 25.0
    assert report.cell_voltage[:4] == [3.3, 3.301, 3.302, 3.303]
    assert report.cell_voltage[12:16] == [3.31, 3.311, 3.312, 3.313]
    assert all(math.isnan(v) for v in report.cell_voltage[4:12])  # frames not received
    assert report.power_supply_health == PowerSupplyHealth.GOOD  # a warning, not a failure
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'LOW_SOC_WARNING' in diag.message


def test_device_soc_unknown_without_capacity_and_cells_follow_config():
    device = std_device(**{'config.cells': 12})
    device.handle_frame(30, STATUS, 1.0)
    report = device.battery_report()
    assert math.isnan(report.percentage) and len(report.cell_voltage) == 12
    assert math.isnan(report.current)  # no ID 40: no shunt, unknown


def test_evms3_status_is_never_published_and_blocks_write_config():
    device = std_device(**{f'config.{k}': v for k, v in CONFIG.items()})
    assert not device.handle_frame(30, EVMS3_STATUS, 1.0)
    assert device.frames_malformed == 1 and 'BMS16 marker' in device.last_malformed
    assert not device.battery_report().present
    with pytest.raises(RefusedCommand, match='byte 5 = 255'):
        device.config_frames()
    device.handle_frame(30, STATUS, 2.0)
    assert [(f.arbitration_id, f.data) for f in device.config_frames()] == GOLDEN_WRITE


def test_ack_names_the_error_reported_and_is_refused_without_one():
    device = std_device()
    with pytest.raises(RefusedCommand):
        device.ack_frame()  # nothing heard yet
    device.handle_frame(30, bytes.fromhex('02 00 00 00 00 FF 00 00'), 1.0)
    with pytest.raises(RefusedCommand, match='no error'):
        device.ack_frame()
    device.handle_frame(30, STATUS, 1.0)
    assert device.ack_frame() == Frame(37, b'\x0a', True)
    assert device.power_off_frame() == Frame(39, b'', True)
    assert device.reset_soc_frame() == Frame(38, b'', True)


def _declare(values):
    def declare(name, spec):
        return values.get(name, spec.default)
    return declare


def test_variant_parameter_picks_the_wire_form():
    default = DeviceSet(['bms16'], _declare({})).devices['bms16']
    assert type(default).__name__ == 'Bms16Device' and 500 in default.arbitration_ids
    standard = DeviceSet(['bms16'], _declare({'bms16.variant': 'standard'})).devices['bms16']
    assert type(standard).__name__ == 'Bms16StdDevice'
    assert standard.frame_ids == {(30, True), (40, True), (301, True), (302, True),
                                  (311, True), (312, True)}
    with pytest.raises(ValueError, match='no variant'):
        DeviceSet(['bms16'], _declare({'bms16.variant': 'evms'}))


def test_base_id_overlapping_the_fixed_ids_is_refused():
    with pytest.raises(ConfigError, match='overlap'):
        DeviceSet(['bms16'], _declare({'bms16.variant': 'standard', 'bms16.base_id': 35}))


def test_parameter_page_and_example_cover_every_standard_form_parameter():
    from pathlib import Path
    import subprocess
    import sys

    import yaml
    root = Path(__file__).resolve().parents[1]
    # doc/parameters.md is these tables (the doc build runs the script)
    tables = subprocess.run([sys.executable, str(root / 'scripts' / 'param_table.py')],
                            capture_output=True, text=True, timeout=60, cwd=root,
                            check=True).stdout
    standard = tables.split('With `bms16.variant: standard`', 1)[1]
    specs = device_params(registry.device_class('bms16', 'standard'))
    missing = [s.key for s in specs if (s.key.startswith('config.') or s.key == 'base_id')
               and f'| `bms16.{s.key}` |' not in standard]
    assert not missing and '| `bms16.variant` |' in tables, missing
    assert '| `bms16.base_id` | int | 0x1E | 0x0..0x1FFFFFFF |' in standard
    example = yaml.safe_load((root / 'config' / 'bms16_standard.yaml').read_text())
    bms16 = example['/**']['ros__parameters']['bms16']
    assert bms16['variant'] == 'standard'
    assert set(bms16['config']) == {s.key[len('config.'):] for s in specs
                                    if s.key.startswith('config.')}
    for name, value in bms16['config'].items():
        check_config_value(name, value)  # every example value is one the wire allows


@settings(max_examples=300, deadline=None)
@given(st.sampled_from([30, 40, 301, 302, 311, 312]), st.binary(max_size=8))
def test_any_frame_decodes_or_is_malformed_and_never_crashes_the_device(frame_id, data):
    assert_decodes_or_malformed(Bms16StdCodec(), frame_id, data)
    device = std_device()
    device.handle_frame(frame_id, data, 0.0)  # never raises
    report = device.battery_report()
    assert math.isnan(report.voltage) or 0 <= report.voltage <= 6553.5


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 5), st.integers(0, 16), st.integers(0, 0xFFFF), st.integers(0, 1600),
       st.integers(0, 240))  # 16 cells of at most 10 V; at most 200 degC
def test_status_round_trip(state, error, ah, volts, temp):
    data = bytes([state | error << 3, ah >> 8, ah & 0xFF, volts >> 8, volts & 0xFF, 255, 0,
                  temp])
    codec = Bms16StdCodec()
    assert codec.encode(codec.decode(30, data)).data == data
