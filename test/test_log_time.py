"""
Stamps on the time the frame was on the bus.

A replay stamps on its log time (and publishes /clock from it), a live bus on the driver's
receive time with can.use_bus_time.

The log and the frames carry timestamps of September 2026, far from the host clock of any
test run, so a stamp taken from the host clock cannot pass for one taken from the frame.
"""
import threading
import time

import can
import pytest
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState

from ams_can_bridge.demo_rig import build_simulators, device_parameters, DEVICES
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.ros.bridge_node import BridgeNode
from ams_can_bridge.sim.recording import write_log
from helpers import device_reference, ros_context, wait_for

LOG_START = 1_790_000_000.0
BANKS = 2


def ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


class Listener(Node):
    """Collect battery_state header stamps per device, and /clock."""

    def __init__(self, context, names) -> None:
        super().__init__('log_time_listener', context=context)
        self.lock = threading.Lock()
        self.stamps: dict[str, list[int]] = {name: [] for name in names}
        self.clock_ns: list[int] = []
        for name in names:
            self.create_subscription(BatteryState, f'{name}/battery_state',
                                     self._collector(name), 10000)
        self.create_subscription(Clock, '/clock', self._on_clock, 1000)

    def _collector(self, name: str):
        return lambda msg: self._battery(name, msg)

    def _battery(self, name: str, msg: BatteryState) -> None:
        if msg.present:
            with self.lock:
                self.stamps[name].append(ns(msg))

    def _on_clock(self, msg: Clock) -> None:
        with self.lock:
            self.clock_ns.append(msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)


def spin(context, *nodes):
    executor = MultiThreadedExecutor(num_threads=3, context=context)
    for node in nodes:
        executor.add_node(node)
    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    return executor, thread


def test_replay_stamps_on_log_time_and_publishes_clock(tmp_path):
    log = str(tmp_path / 'bus.log')
    write_log(log, list(build_simulators(BANKS, DEVICES).values()), 4.0, start=LOG_START)
    reference = device_reference(log, DEVICES, device_parameters(BANKS))
    with ros_context() as ctx:
        values = {'devices': list(DEVICES), **device_parameters(BANKS),
                  'can.interface': 'replay', 'can.channel': log, 'can.replay_rate': 4.0,
                  'can.replay_clock': True}
        bridge = BridgeNode(context=ctx, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
        listener = Listener(ctx, DEVICES)
        executor, thread = spin(ctx, bridge, listener)
        try:
            wait_for(lambda: bridge.can_io.status().state == 'replay finished', 20.0,
                     'the replay to finish')
            want = sum(len(v) for v in reference.values())
            wait_for(lambda: sum(len(v) for v in listener.stamps.values()) >= want, 10.0,
                     'every battery_state of the replay')
            time.sleep(0.1)  # the last /clock tick
        finally:
            executor.shutdown(timeout_sec=2.0)
            thread.join(timeout=3.0)
            bridge.destroy_node()
            listener.destroy_node()
    for name in DEVICES:
        got = [round(s / 1000) for s in listener.stamps[name]]
        assert got == [round(s * 1e6) for s, _ in reference[name]], name
    clock = listener.clock_ns
    with can.LogReader(log) as reader:
        last_frame = max(msg.timestamp for msg in reader)
    assert len(clock) >= 10, 'a 1 s replay at rate 4 gives ~100 /clock ticks'
    assert clock == sorted(clock), '/clock went backwards'
    assert LOG_START * 1e9 <= clock[0] and round(clock[-1] / 1000) == round(last_frame * 1e6)


def test_replay_clock_needs_a_replay():
    with ros_context() as ctx, pytest.raises(ConfigError, match='replay_clock'):
        BridgeNode(context=ctx, parameter_overrides=[
            Parameter('can.interface', value='virtual'),
            Parameter('can.channel', value='log_time_no_replay'),
            Parameter('can.replay_clock', value=True)])


@pytest.mark.parametrize('use_bus_time', [True, False])
def test_live_bus_time(use_bus_time):
    channel = f'log_time_bus_{use_bus_time}'
    # python-can's virtual bus keeps the sender's timestamp with preserve_timestamps: the
    # "driver's receive time" of this test, a moment of September 2026.
    sender = can.Bus(interface='virtual', channel=channel, preserve_timestamps=True)
    frame_time = LOG_START + 0.123456
    with ros_context() as ctx:
        bridge = BridgeNode(context=ctx, parameter_overrides=[
            Parameter('can.interface', value='virtual'),
            Parameter('can.channel', value=channel),
            Parameter('can.use_bus_time', value=use_bus_time),
            Parameter('devices', value=['ivt_s'])])
        listener = Listener(ctx, ['ivt_s'])
        executor, thread = spin(ctx, bridge, listener)
        try:
            wait_for(lambda: bridge.can_io.status().connected, 10.0, 'the bus')
            sim = build_simulators(1, ('ivt_s',))['ivt_s']
            before = time.time()
            deadline = time.monotonic() + 10.0
            t = 0.0
            while not listener.stamps['ivt_s'] and time.monotonic() < deadline:
                for frame in sim.tick(t):
                    sender.send(can.Message(arbitration_id=frame.arbitration_id,
                                            is_extended_id=frame.is_extended_id,
                                            data=frame.data, timestamp=frame_time))
                t += 0.01
                time.sleep(0.01)
            assert listener.stamps['ivt_s'], 'no battery_state'
        finally:
            executor.shutdown(timeout_sec=2.0)
            thread.join(timeout=3.0)
            bridge.destroy_node()
            listener.destroy_node()
            sender.shutdown()
    stamp = listener.stamps['ivt_s'][0] / 1e9
    if use_bus_time:
        assert round(stamp * 1e6) == round(frame_time * 1e6)
    else:
        assert before - 1.0 <= stamp <= time.time()
