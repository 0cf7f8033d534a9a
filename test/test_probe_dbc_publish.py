# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe tells what a dbc mapping would publish, and writes the timeouts it heard (issue 35.8, 35.5).

The Nissan Leaf battery's messages (test/fixtures/nissan_leaf: LB_SOC in 0.1 % under the
unit ``%+1``) with a team's mappings given as ``--dbc --mapping``; the Orion BMS 2 profile
on an Orion whose utility set 0x6B0/0x6B1 to once a second (frames of the WE-EV capture).
"""
from __future__ import annotations

from pathlib import Path

import pytest

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.probe.dbc import DbcRecogniser
from ams_can_bridge.probe.recognise import recognise
from ams_can_bridge.probe.traffic import Traffic

LEAF = Path(__file__).resolve().parent / 'fixtures' / 'nissan_leaf' / 'leaf_battery.dbc'
LEAF_55B = bytes.fromhex('C940AA0000000000')  # LB_SOC 805, LB_ALU_ANSWER 0xAA
LEAF_1DB = bytes.fromhex('0000B40000000000')  # 0 A, 360 V
ORION_6B1 = bytes.fromhex('00120004141100F4')
ORION_6B0 = bytes.fromhex('00000B08A10162CF')


def leaf_traffic() -> Traffic:
    traffic = Traffic()
    for n in range(20):
        traffic.add(0x1DB, False, LEAF_1DB, 0.01 * n)
        if n % 10 == 0:
            traffic.add(0x55B, False, LEAF_55B, 0.01 * n + 0.005)
    return traffic


def leaf_candidate(tmp_path: Path, state: str):
    mapping = tmp_path / 'leaf.yaml'
    mapping.write_text('primary: x1DB\nbattery_state:\n  voltage: x1DB.LB_Total_Voltage\n'
                       f'  current: x1DB.LB_Current\n{state}', encoding='utf-8')
    [cand] = DbcRecogniser([(str(LEAF), str(mapping))])(leaf_traffic(), [])
    return cand


def test_the_leaf_mapping_as_written_is_refused_naming_the_unit_to_give(tmp_path):
    with pytest.raises(ConfigError) as info:
        leaf_candidate(tmp_path, '  percentage: x55B.LB_SOC\n')
    assert "x55B.LB_SOC has unit '%+1'" in str(info.value)
    assert 'give its unit with unit:' in str(info.value)


def test_a_mapping_that_would_publish_805_percent_is_said_and_not_written(tmp_path):
    cand = leaf_candidate(tmp_path, '  percentage: {signal: x55B.LB_SOC, unit: "%"}\n')
    assert cand.confidence < 0.5
    assert any(n.startswith('not written: x55B.LB_SOC = 805 %+1 (implausible for percentage')
               for n in cand.notes), cand.notes
    assert any('count as malformed' in e for e in cand.evidence)


def test_a_good_mapping_says_what_the_bridge_publishes_and_a_guessed_unit(tmp_path):
    cand = leaf_candidate(tmp_path, '  percentage: {signal: x55B.LB_SOC, unit: "0.1 %"}\n'
                          '  design_capacity: x55B.LB_ALU_ANSWER\n')
    assert cand.confidence == 1.0
    assert 'the bridge would publish 360 V, 0 A, SoC 80.5 %, temperature unknown' \
        in cand.evidence
    assert any(n.startswith('mapping warning: battery_state.design_capacity: '
                            "x55B.LB_ALU_ANSWER has unit ''") for n in cand.notes), cand.notes


def test_an_orion_sending_once_a_second_gets_its_timeouts_written():
    traffic = Traffic()
    for n in range(6):
        traffic.add(0x6B0, False, ORION_6B0, float(n))
        traffic.add(0x6B1, False, ORION_6B1, n + 0.5)
    cand = next(c for c in recognise(traffic).written if c.name == 'orion')
    settings = {s.key: s for s in cand.settings}
    assert settings['timeouts'].value == ['MSGID_0X6B1=3']
    assert 'MSGID_0X6B1 heard every 1 s, its timeout would be 0.52 s' in settings['timeouts'].why
    assert settings['stale_timeout'].value == 5.0
    assert any(e.startswith('the bridge would publish 282.4 V, 0 A, SoC 80.5 %, 20 degC')
               for e in cand.evidence), cand.evidence
