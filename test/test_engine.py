# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The engine without ROS: frames in, what a sink receives out, on a hand-driven clock.

The race test drives the two threads of a live bridge (the bus thread's primary frame and
the periodic thread's stale message) into the one order that used to go wrong: a stale
check said "silent", a fresh frame then published present: true, and the stale message
decided before it was published after it, so the last word on a live device was "absent".
"""
from __future__ import annotations

import dataclasses
import threading

from ams_can_bridge import registry
from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.core import Engine, Schedule
from ams_can_bridge.offline.params_file import FileParams
from helpers import Clock

STATUS_ID = 500  # BMS16 status frame (primary): b0 error, b1 SoC, b2..3 0.1 V LE, ...
# error 0, SoC 70 %, 51.0 V, 0.0 A (raw 32768 LE = 00 80), 22 degC: written by hand
STATUS = bytes([0x00, 0x46, 0xFE, 0x01, 0x00, 0x80, 0x16])


class ListSink:
    """Every emitted message, in order."""

    def __init__(self) -> None:
        self.battery_msgs: list[tuple[str, bool, float]] = []
        self.diagnostic_msgs: list[list[tuple[str, int]]] = []
        self.hook = None

    def battery(self, name, frame_id, report, arrays, stamp) -> None:
        if self.hook is not None:
            self.hook(report)
        self.battery_msgs.append((name, report.present, stamp))

    def diagnostics(self, statuses, stamp) -> None:
        self.diagnostic_msgs.append([(name, int(r.level)) for name, r in statuses])

    def clock(self, stamp) -> None:
        pass


def make_engine(clock: Clock, stale_timeout: float = 0.5) -> tuple[Engine, ListSink]:
    params = FileParams({'devices': ['bms16'], 'bms16.type': 'bms16',
                         'bms16.stale_timeout': stale_timeout})
    device_set = DeviceSet(['bms16'], params.declare, clock=clock)
    sink = ListSink()
    status = BusStatus(state=BusState.CONNECTED, reason='', frames_in=0, frames_out=0,
                       frames_dropped_tx=0, error_frames=0, reconnects=0, hardware_id='x')
    engine = Engine(device_set, sink, status_prefix='bridge', interface='virtual',
                    bus_status=lambda: status, now=clock, monotonic=clock)
    return engine, sink


def test_a_primary_frame_is_one_message_with_its_stamp_and_silence_is_present_false():
    clock = Clock(100.0)
    engine, sink = make_engine(clock)
    engine.on_frame(STATUS_ID, STATUS, False, 1234.5)
    assert sink.battery_msgs == [('bms16', True, 1234.5)]
    engine.publish_stale()  # heard just now: nothing
    assert len(sink.battery_msgs) == 1
    clock.now += 1.0
    engine.publish_stale()
    engine.publish_stale()
    assert [m[1] for m in sink.battery_msgs] == [True, False, False]
    assert sink.battery_msgs[-1][2] == clock.now  # stamped when emitted


def test_the_watch_publishes_diagnostics_early_on_a_level_change_only():
    clock = Clock(100.0)
    engine, sink = make_engine(clock)
    engine.watch()  # first look: the levels are new
    assert len(sink.diagnostic_msgs) == 1
    assert sink.diagnostic_msgs[0][0] == ('bridge: bms16', 3)  # STALE: never heard
    engine.watch()
    assert len(sink.diagnostic_msgs) == 1  # nothing changed
    engine.on_frame(STATUS_ID, STATUS, False, 1.0)
    engine.watch()
    assert len(sink.diagnostic_msgs) == 2 and sink.diagnostic_msgs[1][0][1] != 3


def test_a_schedule_runs_the_due_work_at_its_own_moments_in_order():
    moments: list[tuple[str, float]] = []
    now = [0.0]
    schedule = Schedule([(0.5, lambda: moments.append(('d', now[0]))),
                         (0.25, lambda: moments.append(('w', now[0])))],
                        lambda t: now.__setitem__(0, t))
    schedule.run_until(10.0)  # not started: nothing
    schedule.start(10.0)
    schedule.run_until(11.0)
    assert [(k, round(t, 6)) for k, t in moments] == [
        ('w', 10.25), ('d', 10.5), ('w', 10.5), ('w', 10.75), ('d', 11.0), ('w', 11.0)]


def test_a_stale_message_decided_before_a_fresh_frame_is_never_published_after_it():
    clock = Clock(100.0)
    engine, sink = make_engine(clock)
    engine.on_frame(STATUS_ID, STATUS, False, 1.0)
    clock.now += 1.0  # silent: the periodic thread decides to publish present: false
    device = engine.devices['bms16']
    frame_done = threading.Event()
    original = device.snapshot

    def slow_snapshot():
        report = original()
        if not report[0].present and threading.current_thread() is stale_thread:
            # the stale message is decided; now the bus thread takes a fresh frame
            fresh = threading.Thread(target=fresh_frame, daemon=True)
            fresh.start()
            frame_done.wait(timeout=0.5)  # with the fix it cannot finish: it waits for us
        return report

    def fresh_frame():
        engine.on_frame(STATUS_ID, STATUS, False, 2.0)
        frame_done.set()

    device.snapshot = slow_snapshot
    stale_thread = threading.Thread(target=engine.publish_stale, daemon=True)
    stale_thread.start()
    stale_thread.join(timeout=5.0)
    assert frame_done.wait(timeout=5.0)
    presents = [present for _name, present, _stamp in sink.battery_msgs]
    assert presents[-1] is True, f'a stale message overtook a fresh one: {presents}'


def test_the_watch_notices_each_devices_level_and_the_bus_once_each_change():
    # three devices and the bus, each changing alone: the one pass over the devices must
    # see a change of the last as of the first, and publish once per change, not again
    clock = Clock(100.0)
    names = ['ams', 'ivt_s', 'bms16']
    params = FileParams({'devices': names, 'ams.bank_count': 2})
    sink = ListSink()
    status = [BusStatus(state=BusState.CONNECTED, reason='', frames_in=0, frames_out=0,
                        frames_dropped_tx=0, error_frames=0, reconnects=0, hardware_id='x')]
    engine = Engine(DeviceSet(names, params.declare, clock=clock), sink,
                    status_prefix='bridge', interface='virtual', bus_status=lambda: status[0],
                    now=clock, monotonic=clock)
    sims = {name: registry.load(registry.SIMULATORS[name])(
        **({'bank_count': 2} if name == 'ams' else {})) for name in names}
    engine.watch()
    assert len(sink.diagnostic_msgs) == 1  # the first look
    for count, name in enumerate(['bms16', 'ams', 'ivt_s'], start=2):  # last, first, middle
        for step in range(20):  # one second of its frames, on a clock that stands still
            for frame in sims[name].tick(step * 0.05):
                engine.on_frame(frame.arbitration_id, frame.data, frame.is_extended_id,
                                clock.now)
        engine.watch()
        engine.watch()
        assert len(sink.diagnostic_msgs) == count
        assert dict(sink.diagnostic_msgs[-1])[f'bridge: {name}'] != 3  # heard: not STALE
    status[0] = dataclasses.replace(status[0], state=BusState.BUS_OFF)
    engine.watch()
    engine.watch()
    assert len(sink.diagnostic_msgs) == 5
    assert dict(sink.diagnostic_msgs[-1])['bridge: CAN bus'] == 2  # ERROR
    clock.now += 10.0  # all silent: each goes STALE, one publish
    engine.watch()
    engine.watch()
    assert len(sink.diagnostic_msgs) == 6
    assert [level for _, level in sink.diagnostic_msgs[-1]] == [3, 3, 3, 2]
