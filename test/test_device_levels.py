# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Device.diagnostic_level(): the level of diagnostic_report(), without building the values."""
import random

from hypothesis import given, settings, strategies as st
import pytest

from ams_can_bridge import registry
from ams_can_bridge.devices.base import Level
from helpers import Clock

# (device type, device parameters, simulator options)
SETUPS = {
    'ams': ({'bank_count': 2}, {'bank_count': 2}),
    'ivt_s': ({}, {}),
    'evms3': ({'bms12_modules': 3}, {'bms12_modules': 3, 'chargers': 2}),
    'bms16': ({}, {'send_sma': True}),
    'sma': ({}, {}),
}


def sim_frames(device_type: str) -> list[tuple[int, bytes]]:
    """Return 3 s of the simulator's frames (a bms16 also sends the SMA ones)."""
    sim = registry.load(registry.SIMULATORS['bms16' if device_type == 'sma' else device_type])(
        **SETUPS[device_type][1])
    frames = []
    for step in range(60):
        frames += [(f.arbitration_id, bytes(f.data)) for f in sim.tick(step * 0.05)]
    return frames


FRAMES = {t: sim_frames(t) for t in SETUPS}
# (which frame, random bytes (0..8), what to do with them, then wait s)
STEPS = st.lists(st.tuples(st.integers(0, 10 ** 6), st.binary(min_size=0, max_size=8),
                           st.sampled_from(['as sent', 'xor', 'any ID']),
                           st.sampled_from([0.0, 0.01, 0.3, 2.0, 30.0])),
                 min_size=1, max_size=60)


def make(device_type: str):
    clock = Clock()
    cls = registry.device_class(device_type)
    return cls(device_type, SETUPS[device_type][0], clock=clock), clock


def assert_same_level(device) -> None:
    level = device.diagnostic_level()
    assert isinstance(level, Level)
    assert level == device.diagnostic_report().level


@pytest.mark.parametrize('device_type', sorted(SETUPS))
def test_level_of_a_healthy_run_and_of_silence(device_type):
    device, clock = make(device_type)
    assert_same_level(device)  # nothing heard yet
    for can_id, data in FRAMES[device_type]:
        device.handle_frame(can_id, data, clock.now)
        clock.now += 0.005
        assert_same_level(device)
    for wait in (0.3, 1.0, 3.0, 60.0):
        clock.now += wait
        assert_same_level(device)
    assert device.diagnostic_level() == Level.STALE


@pytest.mark.parametrize('device_type', sorted(SETUPS))
@settings(max_examples=100, deadline=None)
@given(steps=STEPS)
def test_level_after_random_frames(device_type, steps):
    # the simulator's frames, some with random bytes, and random data on every ID the
    # device takes (error codes, alarms, charger faults, impossible values), interleaved
    # with silences: whatever the state, the two agree
    device, clock = make(device_type)
    frames = FRAMES[device_type]
    ids = sorted(device.arbitration_ids)
    for can_id, data in frames[:len(frames) // 2]:
        device.handle_frame(can_id, data, clock.now)
    for index, noise, how, wait in steps:
        can_id, data = frames[index % len(frames)]
        if how == 'xor':
            data = bytes(a ^ b for a, b in zip(data, noise.ljust(8, b'\0')))
        elif how == 'any ID':
            can_id, data = ids[index % len(ids)], noise
        clock.now += wait
        device.handle_frame(can_id, data, clock.now)
        assert_same_level(device)


@pytest.mark.parametrize('device_type', sorted(SETUPS))
def test_level_after_random_data_on_each_id_of_a_healthy_device(device_type):
    # one ID at a time on a device that is otherwise fine, so a level only that frame can
    # raise (a charger fault, an SMA alarm) is not hidden behind another
    rng = random.Random(8)
    for can_id in sorted(registry.device_class(device_type)(
            device_type, SETUPS[device_type][0]).arbitration_ids):
        device, clock = make(device_type)
        for sent_id, data in FRAMES[device_type]:
            device.handle_frame(sent_id, data, clock.now)
            clock.now += 0.002
        for _ in range(30):
            data = bytes(rng.randrange(256) for _ in range(rng.choice([0, 1, 2, 6, 7, 8, 8])))
            device.handle_frame(can_id, data, clock.now)
            assert_same_level(device)
