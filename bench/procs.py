# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Child processes of the benchmarks (one role each, selected by the first argument).

    python bench/procs.py subscriber SECONDS OUT.json   rclpy: ivt_s/battery_state arrival
    python bench/procs.py reference CHANNEL SECONDS     python-can recv -> rclpy publish
    python bench/procs.py writer CHANNEL SECONDS RATE BACKGROUND OUT.json
    python bench/procs.py heartbeat CHANNEL SECONDS OUT.json
    python bench/procs.py load CHANNEL SECONDS
    python bench/procs.py virtual MODE SECONDS BANKS MODULES OUT.json

Every role that talks DDS keeps it on this machine (harness sets the environment).
"""
from __future__ import annotations

import json
import os
import struct
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402,F401  (network rule before rclpy is imported)

IVT_CURRENT = 0x521  # IVT-S current result: the ivt_s primary frame
HEARTBEAT = 0x305    # AMS car status, base 0x300 + 0x005


def ivt_current(seq: int) -> bytes:
    """IVT-S current frame carrying seq as its value in mA (the latency probe's tag)."""
    return bytes([0x00, seq & 0x0F]) + int(seq).to_bytes(4, 'big', signed=True)


def current_of(raw: bytes) -> float:
    """BatteryState.current from its serialized (CDR, little-endian) bytes.

    The subscriber takes messages raw: deserializing each one in Python made it the slowest
    part of the flat-out run (it lost messages the bridge had published). Layout: 4 bytes
    encapsulation, stamp (sec, nanosec), frame_id (length incl. NUL, chars, padded to 4),
    then voltage, temperature, current as float32.
    """
    length = struct.unpack_from('<I', raw, 12)[0]
    pos = 4 + ((12 + length + 3) & ~3)
    return struct.unpack_from('<f', raw, pos + 8)[0]


def subscriber(seconds: float, out: str) -> None:
    """Record (tag, arrival time) of every ivt_s/battery_state, and the bridge's own count
    of IVT-S frames taken (its /diagnostics 'frames received', the last one seen)."""
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.node import Node
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import BatteryState
    rclpy.init()
    node = Node('bench_latency_subscriber')
    got: list[tuple[int, float]] = []
    taken = [None]

    def arrived(raw: bytes) -> None:
        now = time.time()
        current = current_of(raw)
        if current == current:  # NaN: a present:false message of a silent device
            got.append((round(abs(current) * 1000), now))

    def diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.endswith(': ivt_s'):
                for kv in status.values:
                    if kv.key == 'frames received':
                        taken[0] = int(kv.value)
    battery = node.create_subscription(BatteryState, '/ivt_s/battery_state', arrived, 1000,
                                       raw=True)
    diag = node.create_subscription(DiagnosticArray, '/diagnostics', diagnostics, 10)
    # A wait set of our own, drained with take() until empty: an rclpy executor rebuilds its
    # wait set per message (~4k messages/s here), slower than the bridge publishes flat out.
    wait_set = _rclpy.WaitSet(2, 0, 0, 0, 0, 0, node.context.handle)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        wait_set.clear_entities()
        wait_set.add_subscription(battery.handle)
        wait_set.add_subscription(diag.handle)
        wait_set.wait(100_000_000)  # ns
        for sub, callback in ((battery, arrived), (diag, diagnostics)):
            while (taken_msg := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                callback(taken_msg[0])
    with open(out, 'w', encoding='utf-8') as stream:
        json.dump({'arrivals': got, 'bridge_frames': taken[0]}, stream)
    node.destroy_node()
    rclpy.shutdown()


def reference(channel: str, seconds: float) -> None:
    """The bare pipeline: python-can recv -> one rclpy publish per IVT-S frame, no decode."""
    import can
    import rclpy
    from sensor_msgs.msg import BatteryState
    rclpy.init()
    node = rclpy.create_node('bench_reference_pipeline')
    pub = node.create_publisher(BatteryState, '/ivt_s/battery_state', 100)
    bus = can.Bus(interface='slcan', channel=channel,
                  **harness.parse_options(harness.SLCAN_OPEN + ['timeout=0.5']))
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end:
            msg = bus.recv(0.1)
            if msg is not None and msg.arbitration_id == IVT_CURRENT:
                out = BatteryState()
                out.current = float(int.from_bytes(msg.data[2:6], 'big', signed=True)) / 1000
                out.header.stamp.sec = int(msg.timestamp)
                pub.publish(out)
    finally:
        bus.shutdown()
        node.destroy_node()
        rclpy.shutdown()


def writer(channel: str, seconds: float, rate: float, background: float, out: str) -> None:
    """Write tagged IVT-S frames at rate/s (and other frames at background/s); log send times."""
    import can
    bus = can.Bus(interface='slcan', channel=channel,
                  **harness.parse_options(harness.SLCAN_OPEN))
    filler = can.Message(arbitration_id=0x123, data=bytes(8), is_extended_id=False)
    sent: dict[int, float] = {}
    start = time.monotonic()
    next_tag, next_fill, seq = start, start, 1
    try:
        while time.monotonic() - start < seconds:
            now = time.monotonic()
            if background and now >= next_fill:
                bus.send(filler)
                next_fill += 1.0 / background
            if now >= next_tag:
                data = ivt_current(seq)
                sent[seq] = time.time()
                bus.send(can.Message(arbitration_id=IVT_CURRENT, data=data,
                                     is_extended_id=False))
                seq += 1
                next_tag += 1.0 / rate
            wait = min(next_tag, next_fill if background else next_tag) - time.monotonic()
            if wait > 0:
                time.sleep(wait)
    finally:
        bus.shutdown()
    with open(out, 'w', encoding='utf-8') as stream:
        json.dump(sent, stream)


def load(channel: str, seconds: float) -> None:
    """Send the simulators' mix towards the bridge (write only: never reads the port)."""
    import can
    from ams_can_bridge import registry
    bus = can.Bus(interface='slcan', channel=channel,
                  **harness.parse_options(harness.SLCAN_OPEN))
    sims = [registry.load(registry.SIMULATORS[n])(name=n, **o) for n, o in (
        ('ams', {'bank_count': 5}), ('ivt_s', {}), ('evms3', {'bms12_modules': 16}),
        ('bms16', {'send_sma': True}))]
    t0 = time.monotonic()
    try:
        while time.monotonic() - t0 < seconds:
            now = time.monotonic() - t0
            for sim in sims:
                for f in sim.tick(now):
                    bus.send(can.Message(arbitration_id=f.arbitration_id, data=f.data,
                                         is_extended_id=f.is_extended_id))
            time.sleep(0.002)
    finally:
        bus.shutdown()


def heartbeat(channel: str, seconds: float, out: str) -> None:
    """On the adapter's side: time every heartbeat frame (nothing else runs here).

    Ends after ``seconds`` or at SIGTERM (then within 0.1 s), and writes the stamps either way.
    """
    import can
    import signal
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    sys.setswitchinterval(0.001)
    bus = can.Bus(interface='slcan', channel=channel,
                  **harness.parse_options(harness.SLCAN_OPEN + ['timeout=0.5']))
    stamps: list[float] = []
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end and not stop.is_set():
            msg = bus.recv(0.1)
            if msg is not None and msg.arbitration_id == HEARTBEAT:
                stamps.append(msg.timestamp)
    finally:
        bus.shutdown()
    with open(out, 'w', encoding='utf-8') as stream:
        json.dump(stamps, stream)


def thread_cpu(tid: int) -> float:
    """Return the CPU seconds of one thread of this process (schedstat: nanoseconds)."""
    try:
        with open(f'/proc/self/task/{tid}/schedstat', encoding='ascii') as stream:
            return int(stream.read().split()[0]) / 1e9
    except (OSError, ValueError, IndexError):
        with open(f'/proc/self/task/{tid}/stat', encoding='ascii') as stream:
            fields = stream.read().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / harness.TICKS


def virtual(mode: str, seconds: float, banks: int, modules: int, out: str) -> None:
    """Simulators + (bridge | bare recv loop) on one in-process virtual bus; CPU without sim."""
    import can
    from ams_can_bridge import registry
    from ams_can_bridge.sim.runner import SimRunner
    channel = f'bench_virtual_{os.getpid()}'
    names = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma')
    options = {'ams': {'bank_count': banks}, 'evms3': {'bms12_modules': modules},
               'bms16': {'send_sma': True}}
    sims = [registry.load(registry.SIMULATORS[n])(name=n, **options.get(n, {}))
            for n in names if n != 'sma']
    sim_bus = can.Bus(interface='virtual', channel=channel)
    frames = [0]
    stop = threading.Event()
    cleanup = []
    if mode == 'bridge':
        import rclpy
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.parameter import Parameter
        from ams_can_bridge.ros.bridge_node import BridgeNode
        rclpy.init()
        node = BridgeNode(parameter_overrides=[
            Parameter('can.interface', value='virtual'), Parameter('can.channel', value=channel),
            Parameter('devices', value=list(names)), Parameter('ams.bank_count', value=banks),
            Parameter('evms3.bms12_modules', value=modules)])
        executor = MultiThreadedExecutor(num_threads=4)
        executor.add_node(node)
        threading.Thread(target=executor.spin, daemon=True).start()

        def count() -> int:
            return node.can_io.frames_in
        cleanup = [executor.shutdown, node.destroy_node, rclpy.shutdown]
    else:
        bus = can.Bus(interface='virtual', channel=channel)

        def loop() -> None:
            while not stop.is_set():
                msg = bus.recv(0.1)
                if msg is not None:
                    frames[0] += 1
        threading.Thread(target=loop, daemon=True).start()

        def count() -> int:
            return frames[0]
        cleanup = [bus.shutdown]
    time.sleep(1.0)
    runner = SimRunner(sim_bus, sims)
    runner.start()
    time.sleep(1.0)  # steady state
    sim_tid = runner._thread.native_id
    c0, s0, n0, t0 = (harness.cpu_seconds(os.getpid()), thread_cpu(sim_tid), count(),
                      time.monotonic())
    time.sleep(seconds)
    c1, s1, n1, t1 = (harness.cpu_seconds(os.getpid()), thread_cpu(sim_tid), count(),
                      time.monotonic())
    runner.stop()
    stop.set()
    for fn in cleanup:
        fn()
    sim_bus.shutdown()
    with open(out, 'w', encoding='utf-8') as stream:
        json.dump({'cpu': (c1 - c0 - (s1 - s0)) / (t1 - t0), 'frames': n1 - n0,
                   'seconds': t1 - t0}, stream)


def flood(seconds: float, out: str) -> None:
    """Flat out on one virtual bus: bare loop rate, then the bridge's, and its losses."""
    import can
    import rclpy
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.parameter import Parameter
    sys.path.insert(0, harness.BENCH.as_posix())
    from bench_bridge_throughput import frame_mix, handled
    from ams_can_bridge.ros.bridge_node import BridgeNode
    mix = frame_mix()
    channel = f'bench_flood_{os.getpid()}'
    sender = can.Bus(interface='virtual', channel=channel)
    bare = can.Bus(interface='virtual', channel=channel)
    sent, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds / 2:
        for msg in mix:
            sender.send(msg)
        sent += len(mix)
        while bare.recv(0) is not None:
            pass
    bare_rate = sent / (time.perf_counter() - start)
    bare.shutdown()
    rclpy.init()
    node = BridgeNode(parameter_overrides=[
        Parameter('can.interface', value='virtual'), Parameter('can.channel', value=channel),
        Parameter('devices', value=['ams', 'ivt_s', 'bms16', 'sma', 'evms3']),
        Parameter('evms3.bms12_modules', value=1)])
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    time.sleep(1.0)
    listened = [m for m in mix if m.arbitration_id != 0x123]
    fanout = sum(len(node.device_set.handle_targets(m.arbitration_id, m.is_extended_id))
                 for m in listened)
    before, rounds, start = handled(node), 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for msg in mix:
            sender.send(msg)
        rounds += 1
    expected = rounds * fanout
    deadline = time.monotonic() + 60
    while handled(node) - before < expected and time.monotonic() < deadline:
        time.sleep(0.05)
    elapsed = time.perf_counter() - start
    done = handled(node) - before
    executor.shutdown()
    node.destroy_node()
    rclpy.shutdown()
    sender.shutdown()
    with open(out, 'w', encoding='utf-8') as stream:
        json.dump({'bare_rate': bare_rate, 'bridge_rate': rounds * len(mix) / elapsed,
                   'sent': expected, 'lost': expected - done}, stream)


if __name__ == '__main__':
    role, args = sys.argv[1], sys.argv[2:]
    if role == 'subscriber':
        subscriber(float(args[0]), args[1])
    elif role == 'reference':
        reference(args[0], float(args[1]))
    elif role == 'writer':
        writer(args[0], float(args[1]), float(args[2]), float(args[3]), args[4])
    elif role == 'heartbeat':
        heartbeat(args[0], float(args[1]), args[2])
    elif role == 'load':
        load(args[0], float(args[1]))
    elif role == 'flood':
        flood(float(args[0]), args[1])
    elif role == 'virtual':
        virtual(args[0], float(args[1]), int(args[2]), int(args[3]), args[4])
    else:
        raise SystemExit(f'unknown role {role}')
