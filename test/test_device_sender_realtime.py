# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The senders' real-time scheduling (realtime.py): granted, refused, off."""
from __future__ import annotations

import errno
import os
import threading

import pytest

from ams_can_bridge import realtime
from ams_can_bridge.devices.sender_thread import PeriodicSender
from ams_can_bridge.parameters import NODE_PARAMS
from ams_can_bridge.protocols.common import Frame
from helpers import wait_for


def scheduling_of_a_sender() -> tuple[int, int]:
    """Start a sender, read its thread's (policy, priority) from the kernel, stop it."""
    seen: list[tuple[int, int]] = []

    def build() -> Frame:
        tid = threading.get_native_id()
        seen.append((os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority))
        return Frame(0x305, b'\x00\x00')
    sender = PeriodicSender('rt-test', 'a test frame', build, lambda frame: (True, ''), 0.01)
    sender.start()
    try:
        wait_for(lambda: seen, 3.0, 'the first slot')
    finally:
        sender.stop()
    return seen[0]


@pytest.fixture
def reset():
    yield
    realtime.use(0)


@pytest.mark.skipif(not hasattr(os, 'sched_setscheduler'), reason='Linux scheduling only')
def test_a_granted_priority_puts_each_sender_thread_on_sched_fifo(reset):
    problem = realtime.use(20)
    if os.geteuid() != 0:  # an ordinary user without an rtprio limit: refused, and why
        assert 'rtprio' in problem and realtime.priority() == 0
        return
    assert problem == ''
    assert realtime.priority() == 20
    # the caller's own scheduling was only borrowed for the check
    assert os.sched_getscheduler(0) == os.SCHED_OTHER
    assert scheduling_of_a_sender() == (os.SCHED_FIFO, 20)


def test_priority_0_leaves_the_default_scheduling(reset):
    assert realtime.use(0) == ''
    assert scheduling_of_a_sender()[0] == os.SCHED_OTHER


def test_a_refused_priority_says_how_to_grant_it_and_keeps_the_default(reset, monkeypatch):
    def refuse(*args: object) -> None:
        raise PermissionError(errno.EPERM, 'Operation not permitted')
    monkeypatch.setattr(os, 'sched_setscheduler', refuse)
    problem = realtime.use(50)
    assert problem.startswith('realtime_priority 50: cannot use SCHED_FIFO '
                              '(Operation not permitted)')
    assert 'rtprio' in problem and 'CAP_SYS_NICE' in problem and 'realtime_priority: 0' in problem
    assert realtime.priority() == 0
    monkeypatch.undo()
    assert scheduling_of_a_sender()[0] == os.SCHED_OTHER


def test_the_parameter_stops_below_the_kernels_own_priority():
    spec = next(p for p in NODE_PARAMS if p.key == 'realtime_priority')
    assert (spec.default, spec.low, spec.high) == (0, 0, 98)


@pytest.mark.ros
def test_the_bridge_runs_its_heartbeat_at_the_priority_it_was_given(rig_factory, reset):
    """realtime_priority reaches the AMS heartbeat's thread through the node's configure."""
    rig = rig_factory({'devices': ['ams'], 'commands_allowed': True, 'commands_enabled': True,
                       'realtime_priority': 30})
    master = rig.node.devices['ams'].master
    rig.wait(lambda: master.thread is not None and master.thread.native_id, what='the heartbeat')
    tid = master.thread.native_id
    if os.geteuid() != 0:
        assert os.sched_getscheduler(tid) == os.SCHED_OTHER  # refused: warned, default kept
        return
    assert (os.sched_getscheduler(tid), os.sched_getparam(tid).sched_priority) \
        == (os.SCHED_FIFO, 30)
