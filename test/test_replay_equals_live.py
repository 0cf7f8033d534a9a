"""
Replay equals live: a recorded bus played back into a fresh bridge publishes the same data.

Live: the simulators run on a virtual bus, a bridge records it (can.record, candump .log).
Replay: fresh bridges play the recording (can.interface replay) in real time and as fast as
possible, from the .log and from a .blf copy. Reference: the real device classes fed the
recorded frames one by one, without ROS (the state after every frame, in order).

What must hold for every device, live and replayed alike, at any replay rate: the
published BatteryStates are exactly the reference's, one per primary frame, in order, value
for value (NaN where unknown). The bridge snapshots the device state at each primary frame,
so neither a later frame nor a fast replay can change or merge what a message carries.
"""
import os
import threading
import time

import can
from diagnostic_msgs.msg import DiagnosticArray
import pytest
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState

from ams_can_bridge.demo_rig import build_simulators, device_parameters
from ams_can_bridge.demo_rig import DEVICES
from ams_can_bridge.ros.bridge_node import BridgeNode
from ams_can_bridge.sim.runner import SimRunner
from helpers import device_reference, same, values_of, wait_for

RECORD_S = 3.0
BANKS = 2
QOS_DEPTH = 10000


def bridge_params(**bus) -> list[Parameter]:
    values = {'devices': list(DEVICES), **device_parameters(BANKS)}
    values.update({f'can.{key}': value for key, value in bus.items()})
    return [Parameter(name, value=value) for name, value in values.items()]


class Collector(Node):
    """Record every BatteryState value of each device and the last CAN bus diagnostics."""

    def __init__(self) -> None:
        super().__init__('replay_test_collector')
        self.lock = threading.Lock()
        self.values: dict[str, list] = {name: [] for name in DEVICES}
        self.bus_values: dict[str, str] = {}
        for name in DEVICES:
            self.create_subscription(BatteryState, f'{name}/battery_state',
                                     lambda msg, n=name: self._battery(n, msg), QOS_DEPTH)
        self.create_subscription(DiagnosticArray, '/diagnostics', self._diagnostics, 100)

    def _battery(self, name: str, msg: BatteryState) -> None:
        if msg.present:  # present: false = the 1 Hz stale heartbeat, no frame behind it
            with self.lock:
                self.values[name].append(values_of(msg))

    def _diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.endswith(': CAN bus'):
                with self.lock:
                    self.bus_values = {kv.key: kv.value for kv in status.values}

    def count(self) -> int:
        with self.lock:
            return sum(len(v) for v in self.values.values())


def wait_settled(collector: Collector, quiet: float = 0.6, timeout: float = 20.0) -> None:
    """Wait until no new message came for ``quiet`` seconds."""
    deadline = time.monotonic() + timeout
    last, since = collector.count(), time.monotonic()
    while time.monotonic() - since < quiet:
        assert time.monotonic() < deadline, 'the bridge kept publishing'
        time.sleep(0.05)
        now = collector.count()
        if now != last:
            last, since = now, time.monotonic()


class Session:
    """A bridge and a collector spinning on their own executor thread."""

    def __init__(self, **bus) -> None:
        self.bridge = BridgeNode(parameter_overrides=bridge_params(**bus))
        self.collector = Collector()
        self.executor = MultiThreadedExecutor(num_threads=3)
        self.executor.add_node(self.bridge)
        self.executor.add_node(self.collector)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def close(self) -> dict[str, list]:
        """Stop; return the published values of each device, in order."""
        self.executor.shutdown(timeout_sec=2.0)
        self.thread.join(timeout=3.0)
        self.bridge.destroy_node()  # closes the recording
        self.collector.destroy_node()
        return self.collector.values


@pytest.fixture(scope='module')
def ros():
    rclpy.init()
    yield
    rclpy.shutdown()


def reference(path: str) -> dict[str, list]:
    """Feed the log to the real device classes: the values after each primary frame."""
    states = device_reference(path, DEVICES, device_parameters(BANKS))
    return {name: [values for _stamp, values in seq] for name, seq in states.items()}


def check_equal(label: str, published: dict[str, list], states: dict[str, list]) -> None:
    """Assert each device published exactly the reference sequence."""
    for name in DEVICES:
        got, want = published[name], states[name]
        first_diff = next((k for k, (a, b) in enumerate(zip(got, want)) if not same(a, b)),
                          None)
        assert len(got) == len(want) and first_diff is None, (
            f'{label}: {name} published {len(got)} messages for {len(want)} primary frames; '
            f'first difference at message {first_diff}: '
            f'{got[first_diff] if first_diff is not None else None} != '
            f'{want[first_diff] if first_diff is not None else None}')


@pytest.mark.slow
def test_replay_publishes_what_live_published(ros, tmp_path):
    live_log = str(tmp_path / 'live.log')
    channel = f'replay_test_{os.getpid()}'
    sim_bus = can.Bus(interface='virtual', channel=channel)
    runner = SimRunner(sim_bus, list(build_simulators(BANKS, DEVICES).values()))
    live = Session(interface='virtual', channel=channel, record=live_log)
    try:
        wait_for(lambda: live.bridge.can_io.status().connected, 10.0, 'the live bus')
        runner.start()
        time.sleep(RECORD_S)  # the length of the recording, not a timing assertion
        runner.stop()
        wait_settled(live.collector)
    finally:
        runner.stop()
        live_values = live.close()
        sim_bus.shutdown()

    states = reference(live_log)
    for name in DEVICES:
        assert len(states[name]) >= 2, f'the recording has {len(states[name])} {name} frames'
    check_equal('live', live_values, states)

    with can.LogReader(live_log) as reader:
        frames = sum(1 for _ in reader)
    blf = str(tmp_path / 'live.blf')
    with can.LogReader(live_log) as reader, can.Logger(blf) as writer:
        for msg in reader:
            writer.on_message_received(msg)

    for path, rate in ((live_log, 1.0), (live_log, 0.0), (blf, 0.0)):
        label = f'replay of {os.path.basename(path)} at rate {rate:g}'
        session = Session(interface='replay', channel=path, replay_rate=rate)
        try:
            wait_for(lambda: session.collector.bus_values.get('state') == 'replay finished',
                     RECORD_S / max(rate, 0.1) + 20.0, f'{label} to finish')
            wait_settled(session.collector)
            bus = dict(session.collector.bus_values)
        finally:
            replayed = session.close()
        assert bus['replay'] == 'finished' and bus['frames in'] == str(frames), (label, bus)
        check_equal(label, replayed, states)
