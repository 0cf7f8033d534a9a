# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe on recorded simulator traffic: its params file, through log2bag, reads what was sent.

For every variant the simulator plays (test/probe_variants.py; the shipped dbc profiles as
``simulator --profile`` plays them too): the simulators' frames are written to a log in
simulated time; ``probe LOG --output`` writes a params file; log2bag converts the log with
exactly that file. What must hold: probe decided the settings the simulator was configured
with (bank count, base IDs, byte order, modules, cells, form, the profile),
and every battery_state and array in the bag equals, message for message and value for
value, the bag log2bag makes with the parameters that describe the simulator (its truth),
with as many cells as the simulated device has, all of them read, and a voltage the pack
can have (an SMA 0x356 in 0.1 V read at 0.01 V would be a tenth of it).
"""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from ams_can_bridge.offline.converter import NODE_NAME
from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.offline.params_file import load_parameters
from ams_can_bridge.probe.main import main as probe_main
from ams_can_bridge.sim.recording import write_log
from helpers import same, values_of
from probe_variants import PROFILE_VARIANTS, Variant, VARIANTS
from shared import rosbags_read

SECONDS = 6.0


def truth_file(path: Path, variant: Variant) -> Path:
    """Write the variant's truth as a nested ROS 2 parameters file."""
    tree: dict = {}
    for key, value in variant.truth.items():
        node = tree
        *parents, leaf = key.split('.')
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': tree}}))
    return path


def run_probe(log: Path, out: Path, capsys) -> tuple[dict, str]:
    """Run probe on a log in this process; return the parameters it wrote and its report."""
    assert probe_main([str(log), '--output', str(out)]) == 0
    report = capsys.readouterr().out
    return load_parameters(str(out), NODE_NAME), report


def battery_topics(bag: Path) -> dict[str, list]:
    """Return every message of the bag but /diagnostics, by topic."""
    return {topic: [m for _, m in msgs] for topic, msgs in rosbags_read(str(bag)).items()
            if topic != '/diagnostics'}


def arrays_equal(a, b) -> bool:
    """Compare two Float32MultiArray messages, NaN equal to NaN."""
    return len(a.data) == len(b.data) and all(
        x == y or (math.isnan(x) and math.isnan(y)) for x, y in zip(a.data, b.data))


@pytest.mark.parametrize('variant', VARIANTS + PROFILE_VARIANTS, ids=lambda v: v.name)
def test_probe_file_reads_what_the_simulator_sent(variant, tmp_path, capsys):
    log = tmp_path / 'bus.log'
    assert write_log(str(log), variant.build(), SECONDS) > 20
    params, report = run_probe(log, tmp_path / 'probe.yaml', capsys)

    assert params['commands_allowed'] is False
    assert params['devices'] == variant.truth['devices'], report
    for key, value in variant.expect.items():
        assert params.get(key) == value, (key, params.get(key), report)
    for key, value in variant.truth.items():  # the truth is decided, never left to a default
        assert params.get(key) == value, (key, report)

    ours = battery_topics(_bag(log, tmp_path / 'probe_bag', params))
    truth = battery_topics(_bag(log, tmp_path / 'truth_bag',
                                load_parameters(str(truth_file(tmp_path / 't.yaml', variant)),
                                                NODE_NAME)))
    assert set(ours) == set(truth)
    for name in variant.truth['devices']:
        assert truth.get(f'/{name}/battery_state'), f'{name}: the truth bag has no message'
    for topic, want in truth.items():
        got = ours[topic]
        assert len(got) == len(want), topic
        for k, (a, b) in enumerate(zip(got, want)):
            if topic.endswith('/battery_state'):
                assert same(values_of(a), values_of(b)), (topic, k)
            else:
                assert arrays_equal(a, b), (topic, k)
    for name, cells in variant.cells.items():
        last = ours[f'/{name}/battery_state'][-1]
        assert len(last.cell_voltage) == cells, name
        assert all(math.isfinite(v) and v > 1.0 for v in last.cell_voltage), name
    for name, (low, high) in variant.volts.items():  # the pack's voltage, not 10x off
        states = [m for m in ours[f'/{name}/battery_state'] if m.present]
        assert states and all(low < m.voltage < high for m in states), name


def _bag(log: Path, bag: Path, params: dict) -> Path:
    convert(str(log), str(bag), params)
    return bag
