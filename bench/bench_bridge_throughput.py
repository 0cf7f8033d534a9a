# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Measure the bridge receive throughput on python-can virtual: does it keep up with a full bus.

A saturated 1 Mbit/s bus carries about 9,000 frames/s. The bridge node (every device type
configured) runs on a MultiThreadedExecutor, publishing as usual; a sender thread in the
same process pushes a mix of the devices' frames (1) as fast as it can and (2) paced at
9,000 frames/s. Printed: frames sent, frames handled by the devices (decoded + malformed),
rates, and the backlog left when the sender stops. The sender shares the GIL with the
bridge, so the numbers are a lower bound of what a separate adapter would allow.

    .venv/bin/python bench/bench_bridge_throughput.py [--seconds 3]
"""
from __future__ import annotations

import argparse
import os
import threading
import time

import can
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.parameter import Parameter

from ams_can_bridge.ros.bridge_node import BridgeNode

# Network rule: DDS discovery stays on this machine (read at rclpy.init, not import).
os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))


def ivt(mux: int, counter: int, value: int) -> bytes:
    """IVT-S result frame (big-endian value)."""
    return bytes([mux, counter & 0x0F]) + value.to_bytes(4, 'big', signed=True)


def frame_mix() -> list[can.Message]:
    """One round of frames of every device (ids as the default config)."""
    frames = [(0x300, bytes([0xC0, 0x24, 180, 30, 66, 1, 0]), False)]
    frames += [(0x311, bytes([(1 << 5) | g] + [180] * 7), False) for g in range(4)]
    frames += [(0x312, bytes([(1 << 5) | g, 20, 21, 22, 23, 24]), False) for g in range(2)]
    frames += [(0x521 + k, ivt(k, 0, 1000 * k), False) for k in range(8)]
    frames += [(500, bytes([0, 81, 0x0B, 0x02, 0x7D, 0x80, 25]), False),
               (501, bytes([0x4A] * 6 + [0x3F]), False),
               (0x356, bytes([0x00, 0x14, 0x67, 0xFF, 0xE7, 0x00]), False),
               (0x355, bytes([64, 0, 98, 0]), False),
               (30, bytes([0x02, 0x04, 0xD2, 0x0D, 0x80, 131, 99, 65]), True),
               (301, bytes([0x0C, 0xE4] * 4), True),
               (0x123, bytes(8), False)]  # an ID nobody listens to
    return [can.Message(arbitration_id=i, data=d, is_extended_id=e) for i, d, e in frames]


def handled(node: BridgeNode) -> int:
    """Return the frames the devices took (decoded or counted malformed), once per frame."""
    return sum(d.frames_received + d.frames_malformed for d in node.devices.values())


def run(node: BridgeNode, bus: can.BusABC, seconds: float, rate: float | None) -> None:
    """Send the mix for `seconds` (paced at `rate` frames/s, or flat out); print results."""
    mix = frame_mix()
    listened = [m for m in mix if m.arbitration_id != 0x123]
    # SMA IDs go to both bms16 and sma: count deliveries as the devices see them
    fanout = sum(len(node.device_set.handle_targets(m.arbitration_id, m.is_extended_id))
                 for m in listened)
    start_handled = handled(node)
    sent = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        for msg in mix:
            bus.send(msg)
        sent += len(mix)
        if rate:
            ahead = sent / rate - (time.perf_counter() - t0)
            if ahead > 0:
                time.sleep(ahead)
    send_time = time.perf_counter() - t0
    expected = sent // len(mix) * fanout
    at_stop = handled(node) - start_handled
    deadline = time.perf_counter() + 30
    while handled(node) - start_handled < expected and time.perf_counter() < deadline:
        time.sleep(0.01)
    total_time = time.perf_counter() - t0
    done = handled(node) - start_handled
    label = f'paced {rate:,.0f}/s' if rate else 'flat out'
    print(f'{label:>16}: sent {sent:,} frames in {send_time:.2f} s '
          f'({sent / send_time:,.0f}/s); device deliveries expected {expected:,}, '
          f'handled {done:,} ({done / total_time:,.0f}/s overall); '
          f'backlog when the sender stopped {expected - at_stop:,}; '
          f'caught up {total_time - send_time:.2f} s later; '
          f'{"all handled" if done >= expected else "FRAMES MISSING"}')


def main() -> None:
    """Run both measurements."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--seconds', type=float, default=3.0)
    args = parser.parse_args()
    rclpy.init()
    channel = f'bench-bridge-{time.time_ns()}'
    node = BridgeNode(namespace='bench', parameter_overrides=[
        Parameter('can.interface', value='virtual'), Parameter('can.channel', value=channel),
        Parameter('devices', value=['ams', 'ivt_s', 'bms16', 'sma', 'evms3']),
        Parameter('evms3.bms12_modules', value=1)])
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    bus = can.Bus(interface='virtual', channel=channel)
    try:
        deadline = time.monotonic() + 10
        while node.can_io.status().state != 'connected' and time.monotonic() < deadline:
            time.sleep(0.05)
        run(node, bus, args.seconds, None)
        run(node, bus, args.seconds, 9000.0)
        print(f'CAN bus status: {node.can_io.status()}')
    finally:
        bus.shutdown()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
