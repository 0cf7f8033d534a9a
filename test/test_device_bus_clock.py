# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The devices' clock: a live frame is timed by its arrival, a replayed one by its log time.

What a device keeps (a cell voltage, the IVT-S current the AMS reports) expires on this
clock. Live, it is the monotonic moment the frame was received, read with its stamp, so a
stall while the frame is handled ages nothing. In a replay it is the log's time
(``ReplayBus.log_time``): a replay publishes what the log says at any rate, however late the
machine delivers a frame, as log2bag and ``helpers.device_reference`` compute it. Before
this, a replay timed values by the moment it handled them: a load stall longer than a
result's timeout (0.5 s for the IVT-S) blanked values the recording had fresh
(test_bridge_replay_equals_live.py failed 4 runs in 6 beside busy loops).
"""
import threading
import time
import uuid

import can

from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.can_io.replay import ReplayBus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.live import device_clock
from ams_can_bridge.protocols import ams as ams_proto
from ams_can_bridge.ros.demo_rig import build_simulators, device_parameters
from ams_can_bridge.sim.recording import write_log
from helpers import device_reference, same, values_of, wait_for

START = 1_790_000_000.0
GAP = 0.5  # s between the frames of the hand-made log (a margin for a busy machine)
NAMES = ('ams', 'ivt_s')
STALL = 1.0  # s: twice the IVT-S stale_timeout (0.5 s), which its pack values follow


def short_log(path, count: int = 3) -> str:
    """Write ``count`` frames GAP s apart from START (IDs no device of these tests takes)."""
    with can.Logger(str(path)) as writer:
        for k in range(count):
            writer.on_message_received(can.Message(
                timestamp=START + k * GAP, arbitration_id=0x700 + k, is_extended_id=False,
                data=bytes([k])))
    return str(path)


def test_replay_log_time_is_the_moment_of_the_frame_being_handled(tmp_path):
    bus = ReplayBus(short_log(tmp_path / 'three.log'), rate=1.0)
    try:
        time.sleep(0.05)
        assert bus.log_time() == START, 'before the first frame: the log starts'
        first = bus.recv(5.0)
        assert first is not None and first.timestamp == START
        assert bus.log_time() == START, 'while a frame is handled, its log time'
        assert bus.recv(0.0) is None, 'the next frame is GAP s away'
        # between frames the log time moves on, never past the frame still to come
        assert START <= bus.log_time() <= START + GAP
        time.sleep(GAP + 0.3)  # a receive loop that falls behind the log
        assert bus.log_time() == START + GAP
        second = bus.recv(5.0)  # overdue: at once
        assert second is not None and second.timestamp == START + GAP
        time.sleep(0.3)  # a handling that stalls
        assert bus.log_time() == START + GAP, 'while a frame is handled, its log time'
        while not bus.finished:
            bus.recv(0.5)
        end = bus.log_time()
        assert end >= START + 2 * GAP
        time.sleep(0.2)
        assert bus.log_time() >= end + 0.2, 'after the log, its time runs on (devices go stale)'
    finally:
        bus.shutdown()


def test_an_as_fast_as_possible_replay_keeps_the_log_times_and_runs_on_at_the_end(tmp_path):
    bus = ReplayBus(short_log(tmp_path / 'three.log'), rate=0.0)
    try:
        seen = []
        while not bus.finished:
            msg = bus.recv(0.5)
            if msg is not None:
                seen.append(bus.log_time())
                time.sleep(0.05)  # handled slowly: still the frame's moment
                assert bus.log_time() == msg.timestamp
        assert seen == [START + k * GAP for k in range(3)]
        time.sleep(0.1)
        assert bus.log_time() >= START + 2 * GAP + 0.1
    finally:
        bus.shutdown()


def test_a_live_frame_is_timed_by_its_arrival_not_by_when_it_is_handled():
    channel = f'bus-clock-{uuid.uuid4().hex}'
    seen = []
    handled = threading.Event()

    def on_frame(arbitration_id, data, extended, stamp):
        entered = time.monotonic()
        at_entry = io.clock()
        time.sleep(0.3)  # a handling that stalls (a busy machine, a slow disk)
        seen.append((entered, at_entry, io.clock()))
        handled.set()

    io = CanIo(BusConfig(interface='virtual', channel=channel), on_frame)
    sender = can.Bus(interface='virtual', channel=channel)
    try:
        io.start()
        assert io.wait_connected(10.0).connected
        before = time.monotonic()
        now = io.clock()
        assert before <= now <= time.monotonic(), 'between frames: monotonic time now'
        sent = time.monotonic()
        sender.send(can.Message(arbitration_id=0x123, data=b'\x01'))
        assert handled.wait(10.0), 'the frame was not handled'
    finally:
        io.stop()
        sender.shutdown()
    entered, at_entry, after_stall = seen[0]
    assert sent <= at_entry <= entered, 'the clock is the moment the frame arrived'
    assert after_stall == at_entry, 'a stall while the frame is handled ages nothing'


def test_the_devices_clock_stays_with_the_last_bus_once_it_is_closed(tmp_path):
    holder = []
    clock = device_clock(lambda: holder[0] if holder else None)
    before = time.monotonic()
    assert before <= clock() <= time.monotonic(), 'no bus yet: monotonic time'
    io = CanIo(BusConfig(interface='replay', channel=short_log(tmp_path / 'three.log'),
                         replay_rate=0.0), lambda *frame: None)
    holder.append(io)
    io.start()
    try:
        wait_for(lambda: io.status().state == 'replay finished', 10.0, 'the replay to end')
        assert clock() >= START + 2 * GAP
    finally:
        io.stop()
    holder.clear()  # the node drops its bus on cleanup
    assert clock() >= START + 2 * GAP, 'the log time, not a jump back to monotonic time'


def test_a_replay_whose_delivery_stalls_shows_what_the_log_shows(tmp_path):
    """
    At rate 1, the bus thread stalls STALL s before two AMS status frames.

    The AMS reports the IVT-S current and voltage, which expire after 0.5 s; a stall of
    1 s delivered late made them NaN in the replay while the log had them fresh. Each
    primary frame must give exactly the reference's values.
    """
    log = str(tmp_path / 'drive.log')
    write_log(log, [build_simulators(1, NAMES)[name] for name in NAMES], 2.0, START)
    params = {k: v for k, v in device_parameters(1).items() if k.split('.')[0] in NAMES}
    want = {name: [values for _, values in seq]
            for name, seq in device_reference(log, NAMES, params).items()}
    holder = []
    devices = DeviceSet(NAMES, lambda name, spec: params.get(name, spec.default),
                        clock=device_clock(lambda: holder[0] if holder else None))
    status_id = devices.devices['ams'].codec.id_of(ams_proto.STATUS)
    got = {name: [] for name in NAMES}
    statuses = [0]

    def on_frame(arbitration_id, data, extended, stamp):
        if arbitration_id == status_id and not extended:
            statuses[0] += 1
            if statuses[0] in (5, 12):
                time.sleep(STALL)  # the machine is busy: this frame is handled late
        for device in devices.handle_frame(arbitration_id, data, extended, stamp):
            got[device.name].append(values_of(device.battery_report()))

    io = CanIo(BusConfig(interface='replay', channel=log, replay_rate=1.0), on_frame,
               devices.filters)
    holder.append(io)
    io.start()
    try:
        wait_for(lambda: io.status().state == 'replay finished', 20.0, 'the replay to end')
    finally:
        io.stop()
    assert statuses[0] >= 12, 'the log has too few AMS status frames for the stalls'
    for name in NAMES:
        first = next((k for k, (a, b) in enumerate(zip(got[name], want[name]))
                      if not same(a, b)), None)
        assert len(got[name]) == len(want[name]) and first is None, (
            f'{name}: {len(got[name])} messages for {len(want[name])} primary frames; first '
            f'difference at {first}: '
            f'{None if first is None else (got[name][first], want[name][first])}')
