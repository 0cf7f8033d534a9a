# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The dbc simulator: in-range traffic encoded through the team's DBC, a pack the device reads.

Also: relative DBC/mapping paths resolve from the package when the working directory does
not hold them, and our AMS example simulated as a dbc BMS reads the same in the built-in
ams device and in the dbc device.
"""
from __future__ import annotations

import math

import cantools
import pytest

from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.devices.dbc.device import DbcDevice
from ams_can_bridge.sim.dbc import DbcSimulator
from dbc_fixtures import OUR_BMS_DBC, OUR_PARAMS
from helpers import Clock, same
from shared import published as _published


def run(sim: DbcSimulator, devices: list, clock: Clock, seconds: float,
        check=None) -> int:
    frames = 0
    for step in range(int(seconds / 0.01)):
        clock.now = step * 0.01
        for frame in sim.tick(clock.now):
            frames += 1
            for device in devices:
                device.handle_frame(frame.arbitration_id, frame.data, clock.now)
            if check is not None:
                check(frame)
    return frames


def test_every_frame_is_in_range_and_the_device_reads_a_plausible_pack():
    db = cantools.database.load_string(OUR_BMS_DBC, strict=True)
    sim = DbcSimulator('dbc', **OUR_PARAMS)
    clock = Clock(0.0)
    device = DbcDevice('dbc', {**OUR_PARAMS, 'stale_timeout': 1.0}, clock)
    ids = set()

    def in_range(frame):
        ids.add(frame.arbitration_id)
        message = db.get_message_by_frame_id(frame.arbitration_id)
        decoded = message.decode(frame.data, decode_choices=False)
        for name, value in decoded.items():
            signal = message.get_signal_by_name(name)
            assert signal.minimum is None or value >= signal.minimum, (name, value)
            assert signal.maximum is None or value <= signal.maximum, (name, value)
    frames = run(sim, [device], clock, 30.0, in_range)
    assert ids == {0x220, 0x222, 0x231, 0x235, 0x240, 0x250}  # every mapped message
    assert frames > 500 and device.frames_malformed == 0
    report = device.battery_report()
    assert report.present and len(report.cell_voltage) == 4
    assert all(3.0 < v < 4.3 for v in report.cell_voltage)
    assert 0.3 <= report.percentage <= 0.9 and math.isfinite(report.current)
    assert device.diagnostic_report().level == 0  # no level rule fires on normal traffic


def test_faults_silent_and_malformed():
    sim = DbcSimulator('dbc', **OUR_PARAMS)
    clock = Clock(0.0)
    device = DbcDevice('dbc', {**OUR_PARAMS, 'stale_timeout': 1.0}, clock)
    sim.faults.malformed = True
    run(sim, [device], clock, 1.0)
    assert device.frames_malformed > 0 and device.frames_received == 0
    sim.faults.malformed, sim.faults.silent = False, True
    assert sim.tick(5.0) == []


def test_relative_paths_resolve_from_the_package_share_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no msg_defs/ or config/ here
    device = DbcDevice('pack', {'dbc_file': 'msg_defs/ams.dbc',
                                'mapping_file': 'config/ams_dbc_mapping.yaml'}, Clock())
    assert (0x300, False) in device.frame_ids
    with pytest.raises(ValueError, match="'msg_defs/nothing.dbc' not found"):
        DbcDevice('pack', {'dbc_file': 'msg_defs/nothing.dbc',
                           'mapping_file': 'config/ams_dbc_mapping.yaml'}, Clock())


def test_ams_example_simulated_reads_the_same_in_both_devices():
    """Our AMS as a simulated dbc BMS: the built-in device agrees, frame after frame."""
    sim = DbcSimulator('pack')  # the defaults: msg_defs/ams.dbc + config/ams_dbc_mapping.yaml
    clock = Clock(0.0)
    ams = AmsDevice('ams', {'bank_count': 5, 'stale_timeout': 0.5}, clock)
    dbc = DbcDevice('pack', {'dbc_file': 'msg_defs/ams.dbc', 'stale_timeout': 0.5,
                             'mapping_file': 'config/ams_dbc_mapping.yaml'}, clock)
    compared = []

    def compare(_frame):
        a, d = _published(ams.battery_report()), _published(dbc.battery_report())
        assert same(a, d), (clock.now, a, d)
        compared.append(a)
    run(sim, [ams, dbc], clock, 3.0, compare)
    assert ams.frames_malformed == 0 and dbc.frames_malformed == 0
    assert len(compared) > 100 and all(math.isfinite(v) for v in compared[-1][-1])
