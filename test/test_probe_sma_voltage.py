# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe's SMA voltage scale (probe/sma_voltage.py) from hand-written frames.

Bytes worked out from doc/protocols.md section 5.2.1 in the comments: 0x351 CVL, DVL at
bytes 0-1 and 6-7 (0.1 V), 0x356 voltage at bytes 0-1 (as sent), 0x373 min / max cell mV at
bytes 0-3, the binary 0x370 max / min cell mV at bytes 4-7. What must hold: the scale the
battery's own evidence settles is written with the values that settled it; what it cannot
settle is a check (commented out), never a guess.
"""
from __future__ import annotations

from ams_can_bridge.probe.output import render
from ams_can_bridge.probe.recognise import recognise
from shared import only, traffic_of

# Discover Lynx II (issue 107 of ai-republic/bms-to-inverter): CVL 0x022E = 55.8 V, DVL
# 0x01B0 = 43.2 V; 0x356 0x020A = 522
DISCOVER_351 = bytes.fromhex('2E02040B040BB001')
DISCOVER_356 = bytes.fromhex('0A0211FFBE000000')
SOC = bytes.fromhex('3E00640000000000')


def sma(frames: list[tuple[int, bytes]], seconds: int = 3):
    """Return the sma candidate of a frame set sent once a second."""
    timed = [(1.0 + t, can_id, data) for t in range(seconds) for can_id, data in frames]
    return only(recognise(traffic_of(timed)), 'sma')


def test_limits_settle_0_1_v_and_the_evidence_names_the_values():
    cand = sma([(0x351, DISCOVER_351), (0x355, SOC), (0x356, DISCOVER_356)])
    scale = cand.setting('voltage_scale')
    assert scale.decided and scale.value == 0.1
    assert scale.why == ('52.2 V at 0.1 V/bit fits the 0x351 limits 43.2..55.8 V, '
                         '5.22 V at 0.01 V/bit does not')
    assert ('voltage scale: 0x356 voltage 522 as sent (5.22 V at 0.01 V/bit, 52.2 V at 0.1 '
            'V/bit), 0x351 limits: charge 55.8 V, discharge 43.2 V, no readable cell voltages') \
        in cand.evidence[-1]


def test_limits_settle_0_01_v():
    # 0x356 0x1461 = 5217: 52.17 V at 0.01 V inside 43.2..55.8 V, 521.7 V far above
    cand = sma([(0x351, DISCOVER_351), (0x356, bytes.fromhex('6114D3FEEB000000'))])
    scale = cand.setting('voltage_scale')
    assert scale.decided and scale.value == 0.01
    assert scale.why.startswith('52.17 V at 0.01 V/bit fits the 0x351 limits')


def test_cells_alone_settle_it_from_a_binary_0x370():
    # Eco-Worthy's 0x370 (doc/protocols.md 5.4): max 0x0CCF = 3.279 V, min 0x0CCA = 3.274 V;
    # 522 is 16 such cells at 0.1 V (52.2 V), 1.6 of them at 0.01 V: no 0x351 needed
    cand = sma([(0x356, DISCOVER_356), (0x370, bytes.fromhex('76006C00CF0CCA0C'))])
    scale = cand.setting('voltage_scale')
    assert scale.decided and scale.value == 0.1
    assert scale.why == ('52.2 V at 0.1 V/bit fits cells of 3.274..3.279 V, 5.22 V at 0.01 '
                         'V/bit does not')
    assert 'no readable 0x351 limits, cells 3.274..3.279 V (0x370)' in cand.evidence[-1]


def test_cells_from_0x373():
    # 0x373 min 0x0CBC = 3.26 V, max 0x0CC6 = 3.27 V, 298 K / 300 K
    cand = sma([(0x356, DISCOVER_356), (0x373, bytes.fromhex('BC0CC60C2A012C01'))])
    scale = cand.setting('voltage_scale')
    assert scale.decided and scale.value == 0.1
    assert 'cells 3.26..3.27 V (0x373)' in cand.evidence[-1]


def test_no_evidence_is_a_check_written_commented_out():
    cand = sma([(0x355, SOC), (0x356, DISCOVER_356)])
    scale = cand.setting('voltage_scale')
    assert not scale.decided and scale.value == 'auto'
    assert scale.why.startswith('check: 0x356 voltage 522 as sent (5.22 V at 0.01 V/bit, '
                                '52.2 V at 0.1 V/bit), no readable 0x351 limits, no readable '
                                'cell voltages')
    assert 'set 0.1 if the 0.01 V reading is a tenth of the pack' in scale.why
    findings = recognise(traffic_of([(1.0 + t, i, d) for t in range(3)
                                     for i, d in ((0x355, SOC), (0x356, DISCOVER_356))]))
    text = render(findings, [], 'test')
    assert '      # voltage_scale: auto\n' in text
    assert 'voltage_scale: 0.1' not in text


def test_limits_that_fit_both_scales_are_a_check():
    # CVL 0x0258 = 60.0 V, DVL 0x0032 = 5.0 V: 5.22 V and 52.2 V both inside 3.75..75 V
    cand = sma([(0x351, bytes.fromhex('5802000000003200')), (0x356, DISCOVER_356)])
    scale = cand.setting('voltage_scale')
    assert not scale.decided
    assert scale.why.startswith('check: 5.22 V at 0.01 V/bit or 52.2 V at 0.1 V/bit: the 0x351 '
                                'limits 5..60 V fit both: set 0.1')


def test_voltages_that_settle_different_scales_are_a_check():
    # against 43.2..55.8 V, 5217 settles 0.01 V and 522 settles 0.1 V: one of them is wrong
    frames = [(1.0, 0x351, DISCOVER_351), (1.0, 0x356, bytes.fromhex('6114D3FEEB000000')),
              (2.0, 0x351, DISCOVER_351), (2.0, 0x356, DISCOVER_356)]
    cand = only(recognise(traffic_of(frames)), 'sma')
    scale = cand.setting('voltage_scale')
    assert not scale.decided
    assert scale.why.startswith('check: the 0x356 voltages sampled disagree: 52.17 V at 0.01 '
                                'V/bit fits the 0x351 limits 43.2..55.8 V, 521.7 V at 0.1 '
                                'V/bit does not; 52.2 V at 0.1 V/bit fits')
    assert '0x356 voltage 522..5217 as sent' in cand.evidence[-1]


def test_a_voltage_that_settles_nothing_beside_one_that_settles_is_said():
    # 0x356 0x0834 = 2100: 21 V or 210 V, neither inside 32.4..69.75 V; 522 settles 0.1 V
    frames = [(1.0, 0x351, DISCOVER_351), (1.0, 0x356, bytes.fromhex('3408000000000000')),
              (2.0, 0x351, DISCOVER_351), (2.0, 0x356, DISCOVER_356)]
    scale = only(recognise(traffic_of(frames)), 'sma').setting('voltage_scale')
    assert scale.decided and scale.value == 0.1
    assert scale.why.endswith('(1 of the 2 0x356 voltages sampled fit both scales or '
                              'neither; none fits only the other)')


def test_the_not_sent_marker_is_no_voltage():
    # 0x356 voltage 0x8000: not sent (section 5.2)
    cand = sma([(0x351, DISCOVER_351), (0x356, bytes.fromhex('008011FFBE000000'))])
    scale = cand.setting('voltage_scale')
    assert not scale.decided and scale.why.startswith('check: no 0x356 voltage heard')
