# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Stamps on the time the frame was on the bus.

A replay stamps on its log time (and publishes /clock from it), a live bus on the driver's
receive time with can.use_bus_time.

The log and the frames carry timestamps of September 2026, far from the host clock of any
test run, so a stamp taken from the host clock cannot pass for one taken from the frame.
"""
import time

import can
import pytest
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from ams_can_bridge.ros.demo_rig import build_simulators, device_parameters, DEVICES
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.ros.bridge_node import BridgeNode
from ams_can_bridge.sim.recording import write_log
from command_rig import battery_topics
from helpers import device_reference, ros_context

LOG_START = 1_790_000_000.0
BANKS = 2


def ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def stamps_of(rig, name: str) -> list[int]:
    """Return the header stamps (ns) of the present battery_state messages of a device."""
    return [ns(m) for m in rig.messages(f'{name}/battery_state') if m.present]


def clock_ns(rig) -> list[int]:
    return [m.clock.sec * 1_000_000_000 + m.clock.nanosec for m in rig.messages('/clock')]


def test_replay_stamps_on_log_time_and_publishes_clock(rig_factory, tmp_path):
    log = str(tmp_path / 'bus.log')
    write_log(log, list(build_simulators(BANKS, DEVICES).values()), 4.0, start=LOG_START)
    reference = device_reference(log, DEVICES, device_parameters(BANKS))
    values = {'devices': list(DEVICES), **device_parameters(BANKS),
              'can.interface': 'replay', 'can.channel': log, 'can.replay_rate': 4.0,
              'can.replay_clock': True}
    rig = rig_factory(values, wait_connected=False, depth=10000,
                      topics={**battery_topics(DEVICES), '/clock': Clock})
    rig.wait(lambda: rig.node.can_io.status().state == 'replay finished', 20.0,
             'the replay to finish')
    want = sum(len(v) for v in reference.values())
    rig.wait(lambda: sum(len(stamps_of(rig, name)) for name in DEVICES) >= want, 10.0,
             'every battery_state of the replay')
    with can.LogReader(log) as reader:
        last_frame = max(msg.timestamp for msg in reader)
    # the last /clock tick: the log time of the last frame (bounded wait, not a sleep)
    rig.wait(lambda: bool(clock_ns(rig)) and round(clock_ns(rig)[-1] / 1000)
             == round(last_frame * 1e6), 10.0, 'the /clock tick of the last frame')
    rig.close()
    for name in DEVICES:
        got = [round(s / 1000) for s in stamps_of(rig, name)]
        assert got == [round(s * 1e6) for s, _ in reference[name]], name
    clock = clock_ns(rig)
    # how many ticks fall into the 1 s of a rate-4 replay depends on the machine's load
    assert len(clock) >= 2, 'the replay published /clock while it played'
    assert clock == sorted(clock), '/clock went backwards'
    assert LOG_START * 1e9 <= clock[0] and round(clock[-1] / 1000) == round(last_frame * 1e6)


def test_replay_clock_needs_a_replay():
    with ros_context() as ctx, pytest.raises(ConfigError, match='replay_clock'):
        BridgeNode(context=ctx, parameter_overrides=[
            Parameter('can.interface', value='virtual'),
            Parameter('can.channel', value='log_time_no_replay'),
            Parameter('can.replay_clock', value=True)])


@pytest.mark.parametrize('use_bus_time', [True, False])
def test_live_bus_time(rig_factory, use_bus_time):
    rig = rig_factory({'can.use_bus_time': use_bus_time, 'devices': ['ivt_s']},
                      topics=battery_topics(['ivt_s']))  # waits for the bus
    # python-can's virtual bus keeps the sender's timestamp with preserve_timestamps: the
    # "driver's receive time" of this test, a moment of September 2026.
    sender = can.Bus(interface='virtual', channel=rig.channel, preserve_timestamps=True)
    frame_time = LOG_START + 0.123456
    try:
        sim = build_simulators(1, ('ivt_s',))['ivt_s']
        before = time.time()
        deadline = time.monotonic() + 10.0
        t = 0.0
        while not stamps_of(rig, 'ivt_s') and time.monotonic() < deadline:
            for frame in sim.tick(t):
                sender.send(can.Message(arbitration_id=frame.arbitration_id,
                                        is_extended_id=frame.is_extended_id,
                                        data=frame.data, timestamp=frame_time))
            t += 0.01
            time.sleep(0.01)
        assert stamps_of(rig, 'ivt_s'), 'no battery_state'
    finally:
        sender.shutdown()
    stamp = stamps_of(rig, 'ivt_s')[0] / 1e9
    if use_bus_time:
        assert round(stamp * 1e6) == round(frame_time * 1e6)
    else:
        assert before - 1.0 <= stamp <= time.time()
