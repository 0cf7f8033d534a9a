# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe on a recording of two batteries: a commented ``pack`` section the bridge reads both ways.

As written, the file configures the two batteries and no pack (the section is commented out);
with the section uncommented as its comment says (its devices line in place of the one above
it), the same file configures a pack of the two as probe named them, with the connection the
voltages suggest, and log2bag writes the pack's topics from the recording.
"""
from __future__ import annotations

import math
from pathlib import Path
import re

import pytest

from ams_can_bridge.offline.converter import NODE_NAME
from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.offline.params_file import load_parameters
from ams_can_bridge.probe.main import main as probe_main
from ams_can_bridge.probe.output import check_file
from ams_can_bridge.sim.ams import AmsSimulator
from ams_can_bridge.sim.bms16 import Bms16Simulator
from ams_can_bridge.sim.evms3 import Evms3Simulator
from ams_can_bridge.sim.ivt_s import IvtSSimulator
from ams_can_bridge.sim.recording import write_log
from shared import rosbags_read

SECONDS = 6.0
FIGURES = ('charge_current_limit', 'discharge_current_limit', 'time_to_empty', 'time_to_full')
KEY = re.compile(r'^(\s*)# ([a-z_0-9]+:( .*)?)$')  # a commented setting (prose starts check:)

CASES = {
    # 14 LiFePO4 cells beside 54 NMC cells: far apart, so not parallel
    'bms16_evms3': (lambda: [Bms16Simulator('bms16', cells=14, send_sma=True),
                             Evms3Simulator('evms3', bms12_modules=6,
                                            cells_per_module=[12, 12, 8, 8, 10, 4],
                                            chargers=0)],
                    ['evms3', 'bms16'], 'series'),
    # two AMS of two banks each at two base IDs: probe names them ams, ams_2; one voltage
    'two_ams': (lambda: [AmsSimulator('ams', base_id=0x300, bank_count=2),
                         AmsSimulator('ams', base_id=0x200, bank_count=2, pad=True)],
                ['ams', 'ams_2'], 'parallel'),
}


def uncomment(text: str) -> str:
    """
    Do what the section's comment says, as a user would.

    Its devices line instead of the one above, and every commented setting from there on
    uncommented (the prose comments stay).
    """
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.lstrip().startswith('# devices:'))
    out = []
    for i, line in enumerate(lines):
        if i < start and line.lstrip().startswith('devices:'):
            continue  # the line the section's devices line replaces
        match = KEY.match(line)
        if i >= start and match and not match.group(2).startswith('check:'):
            line = match.group(1) + match.group(2)
        out.append(line)
    return '\n'.join(out) + '\n'


def probe_file(log: Path, out: Path, capsys) -> str:
    """Run probe on a log, return the params file's text."""
    assert probe_main([str(log), '--output', str(out)]) == 0
    capsys.readouterr()
    return out.read_text()


@pytest.mark.parametrize('case', sorted(CASES))
def test_two_batteries_get_a_commented_pack_that_works_uncommented(case, tmp_path, capsys):
    build, members, connection = CASES[case]
    log = tmp_path / 'bus.log'
    assert write_log(str(log), build(), SECONDS) > 20
    written = tmp_path / 'probe.yaml'
    text = probe_file(log, written, capsys)

    # as written: the bridge's checks pass, two batteries, no pack
    check_file(str(written))
    params = load_parameters(str(written), NODE_NAME)
    assert params['devices'] == members
    assert not [k for k in params if k.startswith('pack')]
    assert '# pack:' in text and f'# members: [{", ".join(members)}]' in text

    # uncommented: a pack of the members as probe named them, the connection guessed
    enabled = tmp_path / 'pack.yaml'
    enabled.write_text(uncomment(text))
    check_file(str(enabled))
    params = load_parameters(str(enabled), NODE_NAME)
    assert params['devices'] == [*members, 'pack']
    assert params['pack.type'] == 'pack'
    assert params['pack.members'] == members
    assert params['pack.connection'] == connection
    assert params['pack.limits.temperature_max'] == [45.0, 50.0, 55.0]

    bag = tmp_path / 'bag'
    convert(str(log), str(bag), params)
    topics = rosbags_read(str(bag))
    member_msgs = sorted((t, name, m) for name in members
                         for t, m in topics[f'/{name}/battery_state'])
    pack = topics['/pack/battery_state']
    assert len(pack) == len(member_msgs) > 10  # one pack message per member message
    for figure in FIGURES:
        assert len(topics[f'/pack/{figure}']) == len(pack)
    latest = {}
    for (_, name, member), (_, msg) in zip(member_msgs, pack):
        latest[name] = member.voltage
    volts = [latest[name] for name in members]
    want = sum(volts) if connection == 'series' else sum(volts) / len(volts)
    assert all(math.isfinite(v) for v in volts)
    assert math.isclose(pack[-1][1].voltage, want, rel_tol=1e-5)


def test_one_battery_gets_no_pack_section(tmp_path, capsys):
    # an AMS and the IVT-S measuring it: one battery (a current sensor is none)
    ams = AmsSimulator('ams', bank_count=1)
    sims = [ams, IvtSSimulator('ivt_s', current_fn=ams.pack_current_a,
                               voltage_fn=ams.pack_voltage_v)]
    log = tmp_path / 'bus.log'
    assert write_log(str(log), sims, SECONDS) > 20
    text = probe_file(log, tmp_path / 'probe.yaml', capsys)
    assert 'devices: [ams, ivt_s]' in text
    assert '# pack:' not in text and 'type: pack' not in text
