# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The one periodic sender (devices/sender_thread.py) under the heartbeat, repeat and keep-alive.

Modelled on python-can's ThreadBasedCyclicSendTask (can/broadcastmanager.py); what the
bridge adds is tested here: an absolute schedule that never bursts, a stop after which
nothing is sent (a send in flight is waited for), a generation that silences a thread of an
earlier start, the hooks for sent and failed frames.
"""
from __future__ import annotations

import threading
import time

import pytest

from ams_can_bridge.devices import sender_thread as periodic_sender
from ams_can_bridge.devices.sender_thread import PeriodicSender, SlotSchedule
from ams_can_bridge.protocols.common import Frame
from helpers import assert_ended, wait_for

FRAME = Frame(0x305, b'\x00')


class Wire:
    """The far end: every frame with its time; can refuse, can hold a send."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.times: list[float] = []
        self.refuse = ''
        self.hold: threading.Event | None = None
        self.holding = threading.Event()

    def send(self, frame: Frame) -> tuple[bool, str]:
        if self.hold is not None:
            self.holding.set()
            self.hold.wait(5.0)
        with self.lock:
            if self.refuse:
                return False, self.refuse
            self.times.append(time.monotonic())
        return True, 'sent'

    def count(self) -> int:
        with self.lock:
            return len(self.times)


def sender_threads(name: str) -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == name and t.is_alive()]


def test_absolute_slots_at_the_period_never_a_burst():
    wire = Wire()
    sender = PeriodicSender('test-sender', 'the test frame', lambda: FRAME, wire.send, 0.01)
    started = time.monotonic()
    assert sender.start() and not sender.start()  # one thread, however often started
    wait_for(lambda: wire.count() >= 50, 10.0, '50 frames')
    assert sender.stop()
    elapsed = time.monotonic() - started
    gaps = sorted(b - a for a, b in zip(wire.times, wire.times[1:]))
    assert gaps[len(gaps) // 2] < 0.02  # the period in use (its accuracy: bench/)
    # one frame per slot at most: a late thread skips slots (counted), never catches up
    assert wire.count() <= elapsed / 0.01 + 2
    assert sender.sent == wire.count()


def test_a_new_period_applies_from_the_next_slot_which_never_moves_later():
    # the absolute grid and its skipped slots: test_device_ams_master.py; issue 34 point 1
    schedule = SlotSchedule(0.05, start=100.0)
    assert schedule.take(100.001) == 0 and schedule.take(100.05) == 0
    schedule.rebase(0.1, 100.06)
    assert schedule.due() == pytest.approx(100.10)  # kept: not one new period after 100.05
    schedule.take(100.10)
    assert schedule.due() == pytest.approx(100.20)  # the new period from then on
    schedule.rebase(0.01, 100.12)  # a shorter one: one new period after the last slot
    assert schedule.due() == pytest.approx(100.12)  # 100.11 has passed: now, never earlier
    with pytest.raises(ValueError):
        schedule.rebase(0.0, 100.2)


def test_the_same_period_again_changes_nothing_however_often():
    schedule = SlotSchedule(0.05, start=100.0)
    schedule.take(100.0)
    for k in range(1000):  # a slider setting the value it has, 1000 times before the slot
        schedule.rebase(0.05, 100.0 + k * 0.00004)
    assert schedule.due() == pytest.approx(100.05)
    schedule.rebase(0.1, 100.01)
    for k in range(100):  # new values every ms: the next slot never moves later
        schedule.rebase(0.1 + (k % 2) * 0.05, 100.01 + k * 0.0001)
        assert schedule.due() <= 100.05 + 1e-9


def test_stop_waits_for_a_send_in_flight_and_nothing_follows_it(monkeypatch):
    # the join gives up early here: the send lock alone must hold stop() until the frame
    # in flight is on the bus
    monkeypatch.setattr(periodic_sender, 'JOIN_TIMEOUT', 0.05)
    wire = Wire()
    sender = PeriodicSender('test-sender', 'the test frame', lambda: FRAME, wire.send, 0.01)
    sender.start()
    wait_for(lambda: wire.count() >= 2, 5.0, 'two frames')
    wire.hold = threading.Event()
    assert wire.holding.wait(5.0)  # a send is on its way now
    thread = sender.thread
    stopped = threading.Event()
    stopper = threading.Thread(target=lambda: (sender.stop(), stopped.set()), daemon=True)
    stopper.start()
    assert not stopped.wait(0.3)  # stop() waits for the frame being sent
    wire.hold.set()
    assert stopped.wait(5.0)
    count = wire.count()  # the frame in flight is in, nothing after it
    assert_ended(thread, 'the sender')
    assert wire.count() == count and not sender.running


def test_a_thread_of_an_earlier_start_never_sends_again():
    wire = Wire()
    sender = PeriodicSender('test-gen', 'the test frame', lambda: FRAME, wire.send, 3600.0)
    for _ in range(20):  # the first frame at once, the next an hour away: each stop wakes it
        sender.start()
        wait_for(lambda: sender.sent == 1, 5.0, 'the first frame')
        sender.stop()
    assert wire.count() == 20 and sender_threads('test-gen') == []


def test_first_slot_one_period_after_the_start():
    wire = Wire()
    sender = PeriodicSender('test-sender', 'the test frame', lambda: FRAME, wire.send, 0.2)
    started = time.monotonic()
    sender.start(first_slot=1)  # slot 0 was sent by someone else
    wait_for(lambda: wire.count() >= 1, 5.0, 'the first frame')
    sender.stop()
    assert wire.times[0] - started >= 0.2 - 0.001


def test_hooks_book_each_send_and_a_failure_can_end_the_sender():
    wire, lines, failures = Wire(), [], []
    booked = []

    def sent(frame, at):
        booked.append((frame, at))
        return f'line {len(booked)}' if len(booked) == 1 else ''

    def failed(reason):
        failures.append(reason)
        return False  # the request ends with it
    sender = PeriodicSender('test-hooks', 'the test frame', lambda: FRAME, wire.send, 0.01,
                            sent=sent, failed=failed, log=lines.append)
    sender.start()
    wait_for(lambda: len(booked) >= 3, 5.0, 'three frames booked')
    thread = sender.thread
    wire.refuse = 'CAN bus fake:0 is not connected'
    assert_ended(thread, 'the sender')  # ended by the hook, from its own thread
    assert not sender.running and failures == ['CAN bus fake:0 is not connected']
    assert sender.failed == 1 and sender.last_error == failures[0]
    assert lines == ['line 1']  # a non-empty line from sent() is logged, once
    assert sender.stop() is False  # nothing left to stop


def test_a_frame_that_cannot_be_built_is_a_failed_slot_the_sender_goes_on():
    wire, reasons = Wire(), []
    count = iter(range(1000))

    def build():
        if next(count) == 1:
            raise ValueError('bank count 9: allowed 1..5')
        return FRAME
    sender = PeriodicSender('test-build', 'the heartbeat', build, wire.send, 0.01,
                            failed=lambda reason: reasons.append(reason) or True)
    sender.start()
    wait_for(lambda: wire.count() >= 3, 5.0, 'frames after the bad one')
    sender.stop()
    assert reasons == ['cannot build the heartbeat: bank count 9: allowed 1..5']


def test_a_new_period_applies_at_once():
    wire = Wire()
    sender = PeriodicSender('test-sender', 'the test frame', lambda: FRAME, wire.send, 3600.0)
    sender.start()
    wait_for(lambda: wire.count() == 1, 5.0, 'the first frame')
    sender.set_period(0.01)  # wakes the thread: the next slot is one new period away
    wait_for(lambda: wire.count() >= 5, 5.0, 'frames at the new period')
    sender.stop()
    assert sender.period == 0.01
    with pytest.raises(ValueError):
        sender.set_period(0.0)
