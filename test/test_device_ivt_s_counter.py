# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
IVT-S result counters as a real sensor advances them: by its measurement cycles, not by frames.

The frames are lines of a real IVT-S on foxBMS 2's bus (test/fixtures/foxbms2, BSD-3-Clause):
every result there is sent every 100 ms and its counter advances by 5 per frame. The golden
counters and values below are read off those lines by hand.
"""
from pathlib import Path

import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.ivt_s.device import IvtSDevice
from ams_can_bridge.protocols.ivt_s import IvtMux
from ams_can_bridge.protocols.ivt_s_commands import ResultConfig, TriggerMode
from helpers import Clock

TRACE = Path(__file__).resolve().parent / 'fixtures' / 'foxbms2' / 'test_log_ivt_s.txt'


def trace_lines():
    """Return (time s, CAN ID, data) of each line: 'Timestamp: t ID: 0525 S Rx DL: 6 04 03 ..'."""
    frames = []
    for line in TRACE.read_text().splitlines():
        words = line.split()
        dlc = int(words[7])
        frames.append((float(words[1]), int(words[3], 16),
                       bytes(int(b, 16) for b in words[8:8 + dlc])))
    return frames


def play(device, clock, ids, until=None):
    """Feed the trace's frames of these IDs at their own times (the device clock follows)."""
    for stamp, can_id, data in trace_lines():
        if until is not None and stamp > until:
            break
        if can_id in ids:
            clock.now = stamp
            device.handle_frame(can_id, data, stamp)


@pytest.fixture
def clock():
    return Clock()


def test_the_trace_is_the_excerpt_the_fixture_readme_describes():
    frames = trace_lines()
    counts = {i: sum(1 for _, can_id, _ in frames if can_id == i)
              for i in (0x35C, 0x35D, 0x525, 0x526, 0x528)}
    assert counts == {0x35C: 9, 0x35D: 16, 0x525: 6, 0x526: 12, 0x528: 16}
    assert frames[0] == (132.164063, 0x525, bytes.fromhex('040300 0000d2'))


def test_wh_every_100_ms_advancing_by_5_is_a_healthy_counter(clock):
    device = IvtSDevice('ivt_s', {}, clock=clock)
    play(device, clock, {0x528})
    # by hand, 0x528 from 132.571956 to 134.069029 s: 05 0a 0f 04 09 0e 03 08 0d 02 07 0c 01
    # 06 0b 00, the value 0x34 = 52 Wh throughout
    values = device.diagnostic_report().values
    assert values['Wh counter'] == '0' and values['Wh (Wh)'] == '52'
    assert values['Wh counter stuck'] == '0' and values['Wh counter jumps'] == '0'
    assert values['Wh counter step'] == '5'
    assert 'counter' not in device.diagnostic_report().message


def test_a_sensor_with_every_result_at_100_ms_is_ok(clock):
    """
    I and U1 of that sensor (MuxID 0 and 1 on 0x35C / 0x35D) at 100 ms, +5 per frame.

    Before the counters were learned per result, this sensor sat at WARN "counter stuck or
    skipping (I, U1)" from its second frame on.
    """
    device = IvtSDevice('ivt_s', {'base_id': 0x35C}, clock=clock)
    play(device, clock, {0x35C, 0x35D}, until=133.571)
    diag = device.diagnostic_report()
    assert diag.level == Level.OK, diag.message
    # 133.570776 s: 35C 00 0d 00 00 03 3c (I 828 mA, counter 13); 133.569197 s: 35D 01 07
    # 00 05 f0 2b (U1 389.163 V, counter 7)
    assert diag.message == '-0.83 A, 389.2 V'
    assert (diag.values['I counter'], diag.values['U1 counter']) == ('13', '7')
    assert diag.values['I counter jumps'] == diag.values['U1 counter jumps'] == '0'


def test_frames_missing_from_the_trace_are_jumps_of_two_and_three_steps(clock):
    device = IvtSDevice('ivt_s', {}, clock=clock)
    play(device, clock, {0x525, 0x526, 0x528})
    values = device.diagnostic_report().values
    # T (0x525): 03 08 | 02 07 | 01 | 00: +5, +10 (132.363 missing), +5, +10, +15
    assert values['T counter jumps'] == '3' and values['T counter stuck'] == '0'
    # W (0x526): 0b 00 | 0a 0f 04 09 0e 03 08 0d 02 07: one +10 (132.364 missing)
    assert values['W counter jumps'] == '1' and values['W counter stuck'] == '0'
    assert values['Wh counter jumps'] == '0'
    assert values['T counter step'] == values['W counter step'] == '5'
    counters = {kind: track.counter for kind, track in device._tracks.items()}
    assert counters[IvtMux.T].lost == 4 and counters[IvtMux.W].lost == 1  # 1 + 1 + 2, 1


def feed(device, clock, kind, counters, period=0.1):
    for counter in counters:
        clock.now += period
        device.handle_frame(0x521 + kind, bytes([kind, counter, 0, 0, 0, 0]), clock.now)


def test_a_counter_out_of_step_is_reported(clock):
    device = IvtSDevice('ivt_s', {}, clock=clock)
    feed(device, clock, IvtMux.I, [3, 8, 13, 2, 7, 9, 14])  # +5 x4, then +2: out of step
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'counter stuck or skipping (I)' in diag.message
    assert diag.values['I counter jumps'] == '1'


def test_a_counter_that_changes_its_step_every_frame_stays_reported(clock):
    device = IvtSDevice('ivt_s', {}, clock=clock)
    feed(device, clock, IvtMux.I, [0, 3, 10, 12, 1, 9] * 4)  # +3 +7 +2 +5 +8 +7 ...
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and 'counter stuck or skipping (I)' in diag.message
    assert int(diag.values['I counter jumps']) == 22  # every advance but the first


def test_a_counter_that_stops_advancing_is_reported(clock):
    device = IvtSDevice('ivt_s', {}, clock=clock)
    feed(device, clock, IvtMux.I, [3, 8, 13, 2, 2, 2])
    diag = device.diagnostic_report()
    assert diag.level == Level.WARN and diag.values['I counter stuck'] == '2'


def test_a_new_cycle_from_the_sensor_restarts_the_step_without_a_warning(clock):
    """After write_config the T result goes from 100 ms (+5) to 20 ms (+1)."""
    device = IvtSDevice('ivt_s', {}, clock=clock)
    feed(device, clock, IvtMux.T, [3, 8, 13, 2])
    answer = bytes([0xA4, 0x02, 0x00, 0x14, 0, 0, 0, 0])  # T: cyclic 20 ms, big-endian
    device.handle_frame(0x511, answer, clock.now)
    feed(device, clock, IvtMux.T, [5, 6, 7, 8, 9], period=0.02)
    values = device.diagnostic_report().values
    assert values['T counter jumps'] == '0' and values['T config'] == 'cyclic 20 ms, ' \
        'big-endian, sign normal'
    assert values['T counter step'] == '1'
    # the same configuration answered again (read_config) keeps the step learned
    device.handle_frame(0x511, answer, clock.now)
    assert device.diagnostic_report().values['T counter step'] == '1'
    assert device.link.configs[IvtMux.T] == ResultConfig(IvtMux.T, TriggerMode.CYCLIC, 20)


def test_a_changed_step_without_an_answer_is_learned_after_three_frames(clock):
    device = IvtSDevice('ivt_s', {}, clock=clock)
    feed(device, clock, IvtMux.T, [3, 8, 13, 2])
    feed(device, clock, IvtMux.T, [3, 4, 5, 6, 7], period=0.02)  # reconfigured by another tool
    counter = device._tracks[IvtMux.T].counter
    assert counter.jumps == 3 and counter.step == 1
