# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Measure the AMS heartbeat: period jitter idle and on a busy bus, and command latencies.

The bridge node (an AMS, commands enabled) runs on a MultiThreadedExecutor with python-can
``virtual``; a separate virtual bus client timestamps every frame (python-can stamps a
virtual frame when it is sent). Printed, per scenario: heartbeat intervals (mean, std, p99,
max, slots skipped by the schedule), then the latency from a service call to its frame on
the bus: a direct frame (set_charge_current, 0x350) and a command carried by the next
heartbeat (sync_time). Everything shares one GIL, so the numbers are an upper bound of
what a dedicated process would see.

    .venv/bin/python bench/bench_heartbeat.py [--period 0.01] [--frames 1000] [--load 4000]
"""
from __future__ import annotations

import argparse
import os
import statistics
import threading
import time

import can
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from ams_can_bridge.ros.bridge_node import BridgeNode

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
HEARTBEAT, CHARGE_CURRENT = 0x305, 0x350


class Capture:
    """Every frame on the channel as (python-can send timestamp, message)."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface='virtual', channel=channel)
        self.frames: list[can.Message] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            msg = self.bus.recv(0.01)
            if msg is not None:
                self.frames.append(msg)

    def heartbeats(self, start: int = 0) -> list[can.Message]:
        """Return heartbeat frames captured from index start on."""
        return [m for m in self.frames[start:] if m.arbitration_id == HEARTBEAT]


def load_sender(channel: str, rate: float, stop: threading.Event) -> threading.Thread:
    """Flood the bus at rate frames/s with frames of other devices (BMS16 status IDs)."""
    def run() -> None:
        bus = can.Bus(interface='virtual', channel=channel)
        msg = can.Message(arbitration_id=500, data=bytes([0, 81, 0x0B, 0x02, 0x7D, 0x80, 25]),
                          is_extended_id=False)
        n, t0 = 0, time.monotonic()
        while not stop.is_set():
            bus.send(msg)
            n += 1
            ahead = n / rate - (time.monotonic() - t0)
            if ahead > 0.001:
                time.sleep(ahead)
        bus.shutdown()
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def intervals_report(name: str, frames: list[can.Message], period: float,
                     skipped: int) -> None:
    """Print interval statistics in ms."""
    stamps = [m.timestamp for m in frames]
    gaps = sorted((b - a) * 1000 for a, b in zip(stamps, stamps[1:]))
    p99 = gaps[min(len(gaps) - 1, int(0.99 * len(gaps)))]
    print(f'{name:>10}: {len(frames)} heartbeats, period {period * 1000:.1f} ms: '
          f'mean {statistics.fmean(gaps):.3f} ms, std {statistics.pstdev(gaps):.3f} ms, '
          f'p99 {p99:.3f} ms, max {gaps[-1]:.3f} ms, min {gaps[0]:.3f} ms, '
          f'slots skipped {skipped}')


def wait_count(capture: Capture, start: int, count: int, timeout: float) -> None:
    """Wait until count heartbeats arrived after start."""
    deadline = time.monotonic() + timeout
    while len(capture.heartbeats(start)) < count and time.monotonic() < deadline:
        time.sleep(0.01)


def call_latency(client_node, capture: Capture, service: str, match, runs: int) -> list[float]:
    """Milliseconds from call_async to the first frame matching match()."""
    client = client_node.create_client(Trigger, service)
    client.wait_for_service(timeout_sec=5.0)
    out = []
    for _ in range(runs):
        start = len(capture.frames)
        t0 = time.time()
        future = client.call_async(Trigger.Request())
        hit = None
        deadline = time.monotonic() + 5.0
        while hit is None and time.monotonic() < deadline:
            hit = next((m for m in capture.frames[start:] if match(m)), None)
            time.sleep(0.0005)
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.001)
        if hit is not None:
            out.append((hit.timestamp - t0) * 1000)
        time.sleep(0.02)
    return out


def latency_report(name: str, values: list[float]) -> None:
    """Print latency statistics in ms."""
    values = sorted(values)
    print(f'{name:>28}: n {len(values)}, mean {statistics.fmean(values):.2f} ms, '
          f'median {statistics.median(values):.2f} ms, max {values[-1]:.2f} ms')


def main() -> None:
    """Run the scenarios and print the numbers."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--period', type=float, default=0.01, help='heartbeat period, s')
    parser.add_argument('--frames', type=int, default=1000, help='heartbeats per scenario')
    parser.add_argument('--load', type=float, default=4000.0, help='busy bus, frames/s')
    args = parser.parse_args()
    channel = f'bench-heartbeat-{os.getpid()}'
    capture = Capture(channel)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = BridgeNode(context=context, parameter_overrides=[
        Parameter('can.interface', value='virtual'), Parameter('can.channel', value=channel),
        Parameter('devices', value=['ams']), Parameter('ams.bank_count', value=1),
        Parameter('ams.heartbeat_period', value=args.period),
        Parameter('ams.charge_current_a', value=10.0),
        Parameter('commands_allowed', value=True), Parameter('commands_enabled', value=True)])
    client = rclpy.create_node('bench_heartbeat_client', context=context)
    executor = MultiThreadedExecutor(num_threads=4, context=context)
    executor.add_node(node)
    executor.add_node(client)
    spin = threading.Thread(target=executor.spin, daemon=True)
    spin.start()
    master = node.devices['ams'].master
    timeout = args.frames * args.period * 3 + 10
    try:
        wait_count(capture, 0, 2, 5.0)
        start, skipped = len(capture.frames), master.stats.missed_slots
        wait_count(capture, start, args.frames, timeout)
        intervals_report('idle', capture.heartbeats(start), args.period,
                         master.stats.missed_slots - skipped)
        stop = threading.Event()
        sender = load_sender(channel, args.load, stop)
        time.sleep(0.2)
        start, skipped = len(capture.frames), master.stats.missed_slots
        t0 = time.monotonic()
        wait_count(capture, start, args.frames, timeout)
        busy = len(capture.frames) - start
        intervals_report('busy bus', capture.heartbeats(start), args.period,
                         master.stats.missed_slots - skipped)
        print(f'{"":>10}  (bus load {busy / (time.monotonic() - t0):.0f} frames/s seen)')
        stop.set()
        sender.join(2)
        latency_report('set_charge_current -> 0x350', call_latency(
            client, capture, '/ams/set_charge_current',
            lambda m: m.arbitration_id == CHARGE_CURRENT, 50))
        latency_report('sync_time -> heartbeat', call_latency(
            client, capture, '/ams/sync_time',
            lambda m: m.arbitration_id == HEARTBEAT and m.data[0] & 0x0F == 6, 50))
    finally:
        executor.shutdown(timeout_sec=2.0)
        node.destroy_node()
        client.destroy_node()
        rclpy.try_shutdown(context=context)
        capture.stop.set()
        capture.thread.join(2)
        capture.bus.shutdown()


if __name__ == '__main__':
    main()
