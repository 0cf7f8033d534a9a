# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Orion BMS 2's checksum byte: the rule on a real capture's frames, the simulator, and probe.

The golden frames are typed from a real car's capture (erikhedb/WE-EV-CAN-Dashboard,
``logs/pcan/candump-2025-11-22_161709.log``, doc/protocols.md [ORION-CAR]): byte 7 is
(ID + 8 + bytes 0..6) & 0xFF in all 302 of its 0x6B0/0x6B1 frames. The simulator of the
``orion_bms2`` profile must send it so, or probe (rightly) doubts it is an Orion.
"""
from __future__ import annotations

from ams_can_bridge.probe.recognise import recognise
from ams_can_bridge.probe.traffic import Traffic
from ams_can_bridge.protocols import orion_bms2
from ams_can_bridge.sim.dbc import DbcSimulator

# (ID, data) as the capture has them
CAPTURE = [(0x6B1, '00000000100C00D5'), (0x6B1, '0068000A100C0047')]


def test_the_rule_holds_on_the_capture():
    for can_id, data in CAPTURE:
        frame = bytes.fromhex(data)
        assert orion_bms2.checksum(can_id, frame) == frame[7]
        assert orion_bms2.checksum_right(can_id, frame)
        assert orion_bms2.with_checksum(can_id, frame[:7] + b'\x00') == frame
    assert not orion_bms2.checksum_right(0x6B1, bytes.fromhex('0068000A100C0048'))


def _simulated(seconds: float) -> list[tuple[float, int, bool, bytes]]:
    sim = DbcSimulator(profile='orion_bms2')
    out = []
    for n in range(int(seconds / 0.004)):
        t = n * 0.004
        out += [(t, f.arbitration_id, f.is_extended_id, bytes(f.data)) for f in sim.tick(t)]
    return out


def test_the_simulator_sends_the_checksum_as_an_orion_does():
    frames = [(i, d) for _, i, _, d in _simulated(1.0) if i in orion_bms2.CHECKSUM_IDS]
    assert {i for i, _ in frames} >= {0x6B0, 0x6B1}
    assert all(orion_bms2.checksum_right(i, d) for i, d in frames), frames[:3]


def test_probe_finds_the_simulated_orion_by_its_checksum():
    traffic = Traffic()
    for t, can_id, ext, data in _simulated(6.0):
        traffic.add(can_id, ext, data, t)
    orion = [c for c in recognise(traffic).devices if c.name.startswith('orion')]
    assert len(orion) == 1 and orion[0].written and orion[0].level == 'high'
    assert any('checksum byte (ID + 8 + bytes 0..6) right in all' in e
               for e in orion[0].evidence), orion[0].evidence
    assert not any('a real Orion BMS 2 sends it right' in n for n in orion[0].notes)


def test_frames_the_orion_checksum_proves_are_no_evidence_for_an_evms3():
    # A car whose ID 0x55A reads as a ZEVA status at 4 Hz (an 11-bit EVMS3 would send such),
    # beside an Orion's cell broadcast 0x36 (= 54, an EVMS3 read-back ID) with its checksum
    from ams_can_bridge.sim.evms3 import Evms3Simulator
    sim = Evms3Simulator(bms12_modules=0)
    status = next(f for t in range(10) for f in sim.tick(t * 0.25)
                  if f.arbitration_id == sim.codec.base_id)
    traffic = Traffic()
    for n in range(24):
        traffic.add(0x55A, False, bytes(status.data), n * 0.25)
        cell = bytes((n % 12, 0x0F, 0xA0, 0x0F, 0x9C, 0x10, 0x00, 0x00))
        traffic.add(0x36, False, orion_bms2.with_checksum(0x36, cell), n * 0.25 + 0.01)
    evms3 = [c for c in recognise(traffic).devices if c.type == 'evms3']
    assert evms3  # the 0x55A status is still a candidate of its own
    for cand in evms3:
        assert (0x36, False) not in cand.ids
        assert not any('configuration read-back 0x036' in e for e in cand.evidence)
        assert any('0x036 not counted as configuration read-back' in n for n in cand.notes)
