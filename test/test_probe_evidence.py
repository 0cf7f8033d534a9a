# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What probe says and decides from hand-written frames, one device family at a time.

Each test builds the traffic frame by frame (bytes worked out from doc/protocols.md in the
comments) and checks the candidate: its IDs, the evidence that names the deciding values,
what it decides and what it leaves as a check (never a silent guess).
"""
from __future__ import annotations

from ams_can_bridge.probe.recognise import recognise
from shared import only, traffic_of


def ivt(base: int, kind: int, counter: int, raw: int, order: str = 'big') -> bytes:
    """Build an IVT-S result frame: MuxID, counter, 32-bit signed value (section 2.1)."""
    return bytes([kind, counter & 0x0F]) + raw.to_bytes(4, order, signed=True)


def test_ivt_s_byte_order_is_decided_by_the_values_and_said():
    # I (MuxID 0) 12.345 A .. 12.360 A and U1 (MuxID 1) 398.5 V, little-endian, base 0x600
    frames = []
    for k in range(20):
        t = 10.0 + 0.1 * k
        frames.append((t, 0x600, ivt(0x600, 0, k, 12_345 + k, 'little')))
        frames.append((t + 0.001, 0x601, ivt(0x600, 1, k, 398_500, 'little')))
    cand = only(recognise(traffic_of(frames)), 'ivt_s')
    assert cand.setting('base_id').value == 0x600
    order = cand.setting('byte_order')
    assert order.decided and order.value == 'little'
    # the deciding values: U1 0x00061494 read little-endian is 398.5 V
    assert 'U1 reads 398.5 V little-endian' in order.why
    assert cand.evidence[0].startswith('results I 0x600 every 100 ms (counter +1), '
                                       'U1 0x601 every 100 ms (counter +1)')
    sign = cand.setting('discharge_positive')
    assert not sign.decided and sign.why.startswith('check: no frame tells the sign')
    assert 'positive in 100% of the frames (mean +12.35 A)' in sign.why


def test_ivt_s_byte_order_no_value_can_tell_is_a_check():
    # every value 0: both byte orders read 0
    frames = [(1.0 + 0.1 * k, 0x521, ivt(0x521, 0, k, 0)) for k in range(10)]
    cand = only(recognise(traffic_of(frames)), 'ivt_s')
    order = cand.setting('byte_order')
    assert not order.decided and order.value == 'big'
    assert order.why.startswith('check: no result tells')


def test_ivt_s_slow_current_gets_a_longer_stale_timeout():
    frames = [(1.0 + k, 0x521, ivt(0x521, 0, k, 1000 + k)) for k in range(6)]  # 1 Hz
    cand = only(recognise(traffic_of(frames)), 'ivt_s')
    stale = cand.setting('stale_timeout')
    assert stale.decided and stale.value == 5.0
    assert stale.why.startswith('I comes every 1 s')


def ams_status(counter: int, banks: int = 2) -> bytes:
    """AMS status, section 1.2: word 0x00 | banks << 5 | IDLE (1); Volt_min, Temp, SOC 66."""
    return bytes([0x00, banks << 5 | 1, 180, 30, 66, counter & 0xFF, 0])


def ams_cells(bank: int, group: int) -> bytes:
    """Seven cells of 3.70 V (185 x 20 mV) of one bank and group (byte 0: bank << 5 | group)."""
    return bytes([bank << 5 | group] + [185] * 7)


def test_ams_bank_count_from_complete_banks_and_a_check_when_one_is_partial():
    status = [(1.0 + 0.1 * k, 0x280, ams_status(k)) for k in range(20)]
    complete = [(1.05, 0x291, ams_cells(b, g)) for b in (1, 2) for g in range(4)]
    cand = only(recognise(traffic_of(status + complete)), 'ams')
    banks = cand.setting('bank_count')
    assert cand.setting('base_id').value == 0x280
    assert banks.decided and banks.value == 2
    assert banks.why == 'cell frames of banks 1..2, each with its groups 0..3 (the status word ' \
        'counts 2)'
    partial = [(1.05, 0x291, ams_cells(1, g)) for g in range(4)] + [
        (1.06, 0x291, ams_cells(2, g)) for g in (0, 1)]
    cand = only(recognise(traffic_of(status + partial)), 'ams')
    banks = cand.setting('bank_count')
    assert not banks.decided and banks.value == 2
    assert 'not every group of each was heard' in banks.why


def test_a_status_whose_counter_never_moves_is_no_ams():
    # the same seven bytes ten times: reads as an AMS status (with cell frames at + 0x11),
    # but an AMS counts its status frames
    frames = [(1.0 + 0.1 * k, 0x280, ams_status(7)) for k in range(10)]
    frames += [(1.05, 0x291, ams_cells(b, g)) for b in (1, 2) for g in range(4)]
    findings = recognise(traffic_of(frames))
    assert findings.devices == []
    unplaced = [(e.can_id, e.count, e.dlc) for e in findings.unplaced]
    assert unplaced == [(0x280, 10, 7), (0x291, 8, 8)]


def zeva_status(pack_dv: int, aux: int) -> bytes:
    """ZEVA status (section 3.1): RUNNING, 50.0 Ah, pack in 0.1 V, aux byte, 98 %, 25 degC."""
    return bytes([2, 0x01, 0xF4]) + pack_dv.to_bytes(2, 'big') + bytes([aux, 98, 65])


def bms12(module: int, t: int, *millivolts: int) -> tuple[int, bytes]:
    return 300 + 10 * module + t, b''.join(v.to_bytes(2, 'big') for v in millivolts)


def test_evms3_cells_per_module_from_the_cells_that_read_a_voltage():
    frames = [(1.0 + 0.25 * k, 30, zeva_status(4000, 132)) for k in range(12)]  # 4 Hz
    for module, cells in enumerate((12, 8, 6)):
        volts = [3600] * cells + [0] * (12 - cells)
        for t in (1, 2, 3):
            can_id, data = bms12(module, t, *volts[4 * (t - 1):4 * t])
            frames.append((1.1, can_id, data))
    cand = only(recognise(traffic_of(frames, extended=True)), 'evms3')
    assert cand.setting('bms12_modules').value == 3
    per_module = cand.setting('config.cells_per_module')
    assert per_module.decided and per_module.value == [12, 8, 6] + [0] * 13
    assert 'BMS12 modules 0: 12 cells, 1: 8 cells, 2: 6 cells' in cand.evidence
    # 400.0 V is a pack a 1x build serves: the multiplier is a check
    assert not cand.setting('voltage_multiplier').decided
    assert not cand.setting('config.pack_capacity_ah').decided


def test_the_bms16_marker_makes_a_standard_form_bms16_not_an_evms3():
    frames = [(1.0 + 0.25 * k, 30, zeva_status(532, 255)) for k in range(12)]
    cells = ((0, 1, [3300] * 4), (0, 2, [3300] * 4), (1, 1, [3300] * 4), (1, 2, [3300, 0, 0, 0]))
    frames += [(1.1, *bms12(module, t, *volts)) for module, t, volts in cells]
    findings = recognise(traffic_of(frames, extended=True))
    cand = only(findings, 'bms16')
    assert [c.type for c in findings.devices] == ['bms16']
    assert cand.setting('variant').value == 'standard'
    assert cand.setting('config.cells').value == 13  # 8 on module 0, 5 on module 1


def test_unplaced_ids_keep_count_dlc_and_rate():
    frames = [(1.0 + 0.5 * k, 0x7E0, bytes([k, 1, 2])) for k in range(5)]
    frames += [(1.2, 0x1ABCDEF0, bytes(8))]
    traffic = traffic_of(frames[:5])
    traffic.add(0x1ABCDEF0, True, bytes(8), 1.2)
    unplaced = recognise(traffic).unplaced
    assert [(e.label(), e.count, e.dlc, e.rate_hz) for e in unplaced] == [
        ('0x7E0', 5, 3, 2.0), ('0x1ABCDEF0', 1, 8, unplaced[1].rate_hz)]
    assert unplaced[1].rate_hz != unplaced[1].rate_hz  # heard once: no rate (NaN)
