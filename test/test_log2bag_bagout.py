# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""offline/bag.py: its own MCAP message write and the array reuse give rosbags' very bytes."""
import math
from pathlib import Path

import pytest

from ams_can_bridge import cdr
from ams_can_bridge.devices.base import BatteryReport
from ams_can_bridge.offline import bag as bag_module
from ams_can_bridge.offline.bag import BagOut
from ams_can_bridge.offline.bag_types import MSGDEFS


def _write_all(path: Path, own_write: bool) -> BagOut:
    out = BagOut(str(path))
    if not own_write:
        out._mcap = None  # rosbags' Writer.write for every message
    report = BatteryReport(stamp=1.5, voltage=400.0, current=-2.0, present=True,
                           cell_voltage=[3.7] * 96, cell_temperature=[25.0] * 16)
    # over 1 MiB of messages: the chunk rosbags closes past 2**20 bytes is closed alike
    for k in range(3000):
        stamp = 1_700_000_000 + k * 0.01
        out.battery_state('/ams/battery_state', report, 'ams', stamp)
        out.multi_array('/ams/temperatures', 2, 3, [20.0, -0.0, math.nan, 1.0, 2.0, k % 7],
                        stamp)
        out.float32('/pack/time_to_go', float(k), stamp)
    out.diagnostics([], 'replay:x', 1_700_000_030.0)
    out.close()
    return out


def test_the_own_mcap_write_gives_the_bytes_of_rosbags_write(tmp_path):
    probe = BagOut(str(tmp_path / 'probe'))
    probe.close()
    if probe._mcap is None:
        pytest.fail('the own MCAP write is off for this rosbags: MCAP_WRITE_KNOWN')
    for side in ('own', 'theirs'):  # the same bag name: the file names are in the metadata
        (tmp_path / side).mkdir()
    own = _write_all(tmp_path / 'own' / 'bag', own_write=True)
    theirs = _write_all(tmp_path / 'theirs' / 'bag', own_write=False)
    assert own.counts == theirs.counts
    own_file = (tmp_path / 'own' / 'bag' / 'bag.mcap').read_bytes()
    assert len(own_file) > 2 ** 20 + 2 ** 19  # more than one chunk
    assert own_file == (tmp_path / 'theirs' / 'bag' / 'bag.mcap').read_bytes()
    assert ((tmp_path / 'own' / 'bag' / 'metadata.yaml').read_text()
            == (tmp_path / 'theirs' / 'bag' / 'metadata.yaml').read_text())


def test_an_array_is_serialized_again_whenever_its_data_changes():
    encoder = cdr.ArrayEncoder()
    data = [1.0, 2.0, math.nan]
    cases = [data, [1.0, 2.0, math.nan], [1.0, 2.5, math.nan], [-0.0, 2.5, 1.0],
             [0.0, 2.5, 1.0]]
    for values in cases:
        assert encoder.encode('/t', 1, 3, values) == cdr.multi_array(1, 3, values)
    data[1] = 9.0  # the device changed its list in place: the kept copy is not that list
    assert encoder.encode('/t', 1, 3, data) == cdr.multi_array(1, 3, data)
    assert encoder.encode('/t', 3, 1, data) == cdr.multi_array(3, 1, data)
    same = [4.0, 5.0, 6.0]
    first = encoder.encode('/u', 1, 3, same)
    assert encoder.encode('/u', 1, 3, list(same)) is first  # unchanged: the kept bytes


def test_the_kept_message_definitions_are_the_jazzy_stores():
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    assert set(MSGDEFS) == {bag_module.BATTERY_STATE, bag_module.MULTI_ARRAY,
                            bag_module.FLOAT32, bag_module.DIAGNOSTIC_ARRAY}
    for msgtype, (msgdef, rihs01) in MSGDEFS.items():
        assert msgdef == store.generate_msgdef(msgtype, ros_version=2)[0], msgtype
        assert rihs01 == store.hash_rihs01(msgtype), msgtype
