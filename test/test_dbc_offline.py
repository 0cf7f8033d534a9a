# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A dbc device offline like the built-in ones: log2bag and replay publish what the device decodes.

The log comes from ``DbcSimulator`` on our hand-written BMS DBC (test/fixtures/our_bms.*);
the reference is the real DbcDevice fed the same log without ROS (helpers.device_reference).
"""
from __future__ import annotations

import time

import can

from ams_can_bridge.offline.log2bag import convert, main
from ams_can_bridge.protocols.dbc_mapping import plan as dbc_plan
from ams_can_bridge.sim.dbc import DbcSimulator
from ams_can_bridge.sim.recording import write_log
from command_rig import battery_topics
from dbc_fixtures import OUR_BMS_DBC, OUR_PARAMS, write_files
from helpers import device_reference, same, values_of
from shared import rosbags_read

SECONDS = 3.0
PARAMS = {f'dbc.{key}': value for key, value in OUR_PARAMS.items()}


def _log(tmp_path) -> str:
    path = str(tmp_path / 'dbc.log')
    frames = write_log(path, [DbcSimulator('dbc', **OUR_PARAMS)], SECONDS)
    assert frames > 50
    return path


def test_log2bag_writes_one_batterystate_per_primary_frame_with_the_devices_values(tmp_path):
    log = _log(tmp_path)
    bag = str(tmp_path / 'bag')
    summary = convert(log, bag, {'devices': ['dbc'], 'diagnostics_period': 0.5, **PARAMS})
    assert summary.bad_entries == 0
    want = device_reference(log, ['dbc'], PARAMS)['dbc']
    topics = rosbags_read(bag)
    got = topics['/dbc/battery_state']
    assert len(want) >= 20 and len(got) == len(want)
    for (_, msg), (_, values) in zip(got, want):
        assert same(values_of(msg), values)
    assert len(got[-1][1].cell_voltage) == 4 and got[-1][1].present
    statuses = [s for _, m in topics['/diagnostics'] for s in m.status
                if s.name == 'ams_can_bridge: dbc']
    assert statuses and statuses[-1].level == 0
    assert any(kv.key == 'BMS_StateEstimation.packSoc [%]' for kv in statuses[-1].values)


def test_replay_publishes_the_reference(rig_factory, tmp_path):
    log = _log(tmp_path)
    want = [values for _, values in device_reference(log, ['dbc'], PARAMS)['dbc']]
    # A lead-in: one frame no device takes (0x7FF; the DBC's IDs are 0x220..0x250), 1 s
    # before the first, played in real time, so the test's subscription is matched (DDS
    # discovery) before the first BatteryState is published; otherwise it can be lost.
    led = str(tmp_path / 'led.log')
    with can.LogReader(log) as reader, can.Logger(led) as writer:
        for k, msg in enumerate(reader):
            if k == 0:
                writer.on_message_received(can.Message(
                    timestamp=msg.timestamp - 1.0, arbitration_id=0x7FF, data=b'',
                    is_extended_id=False))
            writer.on_message_received(msg)
    with can.LogReader(led) as reader:
        frames = sum(1 for _ in reader)
    rig = rig_factory({'devices': ['dbc'], **PARAMS, 'can.interface': 'replay',
                       'can.channel': led, 'can.replay_rate': 1.0},
                      topics=battery_topics(['dbc']), depth=10000, wait_connected=False)
    try:
        rig.wait(lambda: rig.bus_values().get('state') == 'replay finished', 30.0 + SECONDS,
                 'the replay to finish')
        deadline = time.monotonic() + 20.0
        while rig.present_count('dbc/battery_state') < len(want):
            assert time.monotonic() < deadline, 'not every BatteryState arrived'
            time.sleep(0.05)
        bus = rig.bus_values()
    finally:
        rig.close()
    got = [values_of(m) for m in rig.messages('dbc/battery_state') if m.present]
    assert bus['frames in'] == str(frames)
    assert len(got) == len(want) and all(same(a, b) for a, b in zip(got, want))


def test_log2bag_finds_relative_files_beside_its_params_file_and_says_the_warnings(
        tmp_path, monkeypatch, capsys):
    log = _log(tmp_path)
    car = tmp_path / 'car'
    car.mkdir()
    # a broken message the mapping does not read: a warning, and the conversion goes on
    write_files(car, OUR_BMS_DBC.replace('VAL_ 544 mode', 'BO_ 700 Unrelated: 1 BMS\n'
                                         ' SG_ wide : 0|16@1+ (1,0) [0|0] "" BMS\n\n'
                                         'VAL_ 544 mode'))
    params = car / 'params.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [dbc]\n'
                      '    dbc: {dbc_file: our_bms.dbc, mapping_file: pack_mapping.yaml}\n')
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.setattr(dbc_plan, '_params_folders', [])  # main() sets them for the process
    assert main([log, str(tmp_path / 'bag'), '--params-file', str(params)]) == 0
    err = capsys.readouterr().err
    assert 'log2bag: warning: dbc: DBC message Unrelated is broken and unusable: The signal ' \
        'wide does not fit' in err
    assert rosbags_read(str(tmp_path / 'bag'))['/dbc/battery_state']


def test_log2bag_stops_with_exit_2_on_a_mapped_broken_message(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(dbc_plan, '_params_folders', [])  # main() sets them for the process
    files = write_files(tmp_path, OUR_BMS_DBC.replace('error : 8|8@1+', 'error : 2|8@1+'))
    params = tmp_path / 'params.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [dbc]\n'
                      f"    dbc: {{dbc_file: {files['dbc_file']}, "
                      f"mapping_file: {files['mapping_file']}}}\n")
    assert main([_log(tmp_path), str(tmp_path / 'bag'), '--params-file', str(params)]) == 2
    err = capsys.readouterr().err
    assert 'message BMS_State is broken in the DBC (The signals error and mode are ' \
        'overlapping)' in err and 'Traceback' not in err
