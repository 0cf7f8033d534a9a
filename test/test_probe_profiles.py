# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe's recogniser of the shipped dbc profiles, on frames written by hand from their DBCs.

What it decides beyond the IDs (the round trips and the real captures are in
test_probe_roundtrip.py and test_probe_captures.py): values no BMS sends make a match that
is reported and not written; foxBMS cell frames beyond the profile's 18 cells are said and
become a check; an SMA-family battery of another pack stays a device of its own; the
checksum of the Orion frames is evidence.
"""
from __future__ import annotations

from ams_can_bridge.protocols.dbc_profiles import PROFILES
from ams_can_bridge.probe.profiles import SHIPPED
from ams_can_bridge.probe.recognise import recognise
from ams_can_bridge.probe.traffic import Traffic

# The Orion capture's 0x6B1 (test/fixtures/orion_bms2): DCL 18 A, CCL 4 A, 20 / 17 degC
ORION_6B1 = bytes.fromhex('00120004141100F4')
# Its 0x6B0: 0 A, 0x0B08 x 0.1 = 282.4 V, SoC 0xA1 x 0.5 = 80.5 %, relays 0x0162, checksum
ORION_6B0 = bytes.fromhex('00000B08A10162CF')


def orion(traffic: Traffic, first: bytes, t0: float = 0.0) -> None:
    """Add ten 0x6B0 frames every 8 ms and one 0x6B1."""
    for n in range(10):
        traffic.add(0x6B0, False, first, t0 + 0.008 * n)
    traffic.add(0x6B1, False, ORION_6B1, t0 + 0.05)


def by_name(findings, name):
    return next(c for c in findings.devices if c.name == name)


def test_every_shipped_profile_has_its_name_and_title():
    assert set(SHIPPED) == set(PROFILES)


def test_orion_frames_reading_an_impossible_pack_are_reported_not_written():
    # 0x6B0 with Pack_Inst_Voltage 0xFFFF: 6553.5 V, inside the DBC's [0|6553.5] but no
    # pack's; the checksum holds: (0x6B0 + 8 + 0xFF + 0xFF + 0xA1 + 0x01 + 0x62) & 0xFF = 0xBA
    traffic = Traffic()
    orion(traffic, bytes.fromhex('0000FFFFA10162BA'))
    findings = recognise(traffic)
    cand = by_name(findings, 'orion')
    assert not cand.written and cand.confidence < 0.5
    # the device itself refuses it now (issue 35.6): its primary is not heard in range
    assert any(n.startswith('not written: its primary message MSGID_0X6B0') for n in cand.notes)
    assert any('outside the DBC range: Pack_Inst_Voltage (or beyond voltage 0..1500 V)' in e
               for e in cand.evidence), cand.evidence
    assert findings.written == []


def test_orion_with_a_wrong_checksum_is_said():
    traffic = Traffic()
    orion(traffic, ORION_6B0[:7] + b'\x00')
    cand = by_name(recognise(traffic), 'orion')
    assert cand.written and cand.confidence == 0.9  # 2 of 2 messages, no checksum bonus
    assert any('right in 1 of 11 frames' in n for n in cand.notes)  # 0x6B1's holds


def test_an_sma_battery_of_another_pack_stays_a_device_of_its_own():
    # the Pylontech capture's 0x356 02 13 00 00 4A 01: 4866 x 0.01 V = 48.66 V (486.6 V in
    # 0.1 V): neither is the Orion's 282.4 V
    traffic = Traffic()
    orion(traffic, ORION_6B0)
    for n in range(3):
        traffic.add(0x356, False, bytes.fromhex('02130000 4A01'.replace(' ', '')), n * 1.0)
        traffic.add(0x355, False, bytes.fromhex('1A006400'), n * 1.0 + 0.01)
    findings = recognise(traffic)
    assert [c.name for c in findings.written] == ['sma', 'orion']
    assert findings.conflicts == []
    assert {i for i, _ in by_name(findings, 'orion').ids} == {0x6B0, 0x6B1}


def test_the_same_pack_in_sma_frames_is_the_orions_and_a_conflict():
    # 0x356 08 0B ..: 2824 = 282.4 V in 0.1 V, the Orion's pack voltage
    traffic = Traffic()
    orion(traffic, ORION_6B0)
    for n in range(3):
        traffic.add(0x356, False, bytes.fromhex('080B0000C800'), n * 0.1)
    findings = recognise(traffic)
    assert [c.name for c in findings.written] == ['orion']
    (conflict,) = findings.conflicts
    assert conflict.kept.name == 'orion' and conflict.dropped.type == 'sma'
    assert 'kept Orion BMS 2' in conflict.text()


def test_foxbms_cells_beyond_the_profiles_18_are_said_and_a_check():
    # f_CellVoltages (0x250): byte 0 the multiplexer, 4 cells a value; the profile maps 18
    # cells (values 0..4). 00 17 3A 39 D4 ..: cells 0, 1 = 3700, 3701 mV, cell 0 flagged
    # valid (bit 12 = 1), the others not; the same with value 6: cells 24..27, beyond the
    # mapping
    traffic = Traffic()
    for n in range(5):
        traffic.add(0x220, False, bytes.fromhex('0308000100000000'), 0.1 * n)  # IDLE
    traffic.add(0x250, False, bytes.fromhex('00173A39D4000000'), 0.02)
    traffic.add(0x250, False, bytes.fromhex('06173A39D4000000'), 0.12)
    findings = recognise(traffic)
    fox = by_name(findings, 'foxbms2')
    assert fox.written
    assert any('multiplexer values 0, 6 heard, carrying elements 0..3 of the 18 mapped; '
               'values 6 carry more than the mapping reads: the pack has more than 18' in e
               for e in fox.evidence)
    assert any('1 of 18 cell voltages read (3.7)' in e for e in fox.evidence)
    check = fox.setting('mapping_file')
    assert check is not None and not check.decided
    assert 'and more cell voltages were heard' in check.why
