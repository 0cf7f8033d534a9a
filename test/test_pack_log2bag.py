# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""log2bag with a pack: the bag gets the pack's BatteryState and Float32 topics on log time."""
import math

import numpy as np

from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.ros.demo_rig import build_simulators, DEVICES
from ams_can_bridge.sim.recording import write_log
from shared import BANKS, parameters, rosbags_read, SECONDS

FIGURES = ('charge_current_limit', 'discharge_current_limit', 'time_to_empty', 'time_to_full')


def test_the_bag_holds_the_pack_of_two_members_on_log_time(tmp_path):
    log = str(tmp_path / 'bus.log')
    write_log(log, list(build_simulators(BANKS, DEVICES).values()), SECONDS)
    params = dict(parameters(), devices=[*DEVICES, 'pack'], **{
        'pack.type': 'pack', 'pack.members': ['evms3', 'bms16'],
        'pack.max_charge_current': 40.0, 'pack.max_discharge_current': 80.0,
        'pack.max_voltage_difference': 1000.0})
    bag = str(tmp_path / 'bag')
    convert(log, bag, params)
    topics = rosbags_read(bag)
    members = sorted([(t, 'evms3', m) for t, m in topics['/evms3/battery_state']]
                     + [(t, 'bms16', m) for t, m in topics['/bms16/battery_state']],
                     key=lambda e: e[0])
    pack = topics['/pack/battery_state']
    # one pack message per member message, at its log time
    assert [t for t, _ in pack] == [t for t, _, _ in members]
    latest = {}
    checked = 0
    for (t, name, member), (_, msg) in zip(members, pack):
        latest[name] = member
        header_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        assert header_ns == t
        if len(latest) == 2 and all(m.present for m in latest.values()):
            want = (np.float32(latest['evms3'].voltage) + np.float32(latest['bms16'].voltage))
            assert math.isclose(msg.voltage, float(want) / 2, rel_tol=1e-6)
            cells = [*latest['evms3'].cell_voltage, *latest['bms16'].cell_voltage]
            assert np.array_equal(msg.cell_voltage, cells, equal_nan=True)
            checked += 1
    assert checked > 10
    for suffix in FIGURES:
        figures = topics[f'/pack/{suffix}']
        assert [t for t, _ in figures] == [t for t, _ in pack], suffix
    limits = [m.data for _, m in topics['/pack/charge_current_limit']]
    assert limits[-1] == 40.0  # both present, no limit configured to derate it
    statuses = {s.name: s for s in topics['/diagnostics'][-1][1].status}
    assert 'ams_can_bridge: pack' in statuses
