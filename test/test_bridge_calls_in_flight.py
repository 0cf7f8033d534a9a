# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Calls in flight against a disarm and against lifecycle transitions (issue 34, points 2, 3).

Point 2: with the adapter unplugged, four ``ams/start_charging`` calls used to take every
executor thread (the first waited for the bus holding the charger's call lock, three waited
on that lock): the disarm was answered 4 s later and a START went out on replug. Now a
disarm is served at once (one executor thread is always free: ``ros/call_group.py``), no
call waits for the bus holding a device lock, calls beyond the bus-wait slots are refused at
once, and nothing is sent after the disarm.

Point 3: a deactivate, cleanup or shutdown with a call waiting for its answer
(``ivt_s/read_config``, ``evms3/read_config``) used to destroy the services under it
(``InvalidHandle``: the executor stopped, the process exited 1). Now the transition first
ends the calls (answered ``success: false``, "cancelled by <transition>") and destroys the
services only after their callbacks returned; a later configure and activate work.
"""
from __future__ import annotations

import time

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from ams_can_bridge.ros.call_group import COMMAND_THREADS
from ams_can_bridge.ros.bridge_main import EXECUTOR_THREADS
from slcan_peer import SlcanPeer

NODE = '/ams_can_bridge'
IVT_COMMAND = 0x411
EVMS3_REQUEST = 51  # 29-bit: the capture is filtered by ID alone
DISARM_BOUND = 0.5  # s for the disarm's answer through ROS on a loaded machine (issue: 0.1)


def disarm(rig) -> tuple[bool, float]:
    """Set commands_enabled false through the parameter service; (successful, seconds)."""
    started = time.monotonic()
    result = rig.call(SetParameters, f'{NODE}/set_parameters', timeout=30.0, parameters=[
        Parameter('commands_enabled', value=False).to_parameter_msg()]).results[0]
    return result.successful, time.monotonic() - started


def change(rig, transition: int) -> bool:
    return rig.call(ChangeState, f'{NODE}/change_state',
                    transition=Transition(id=transition), timeout=30.0).success


def state(rig) -> str:
    return rig.call(GetState, f'{NODE}/get_state').current_state.label


def test_one_executor_thread_always_stays_for_parameters_and_transitions():
    assert COMMAND_THREADS < EXECUTOR_THREADS


def test_a_disarm_is_answered_at_once_with_four_start_charging_calls_on_an_unplugged_bus(
        rig_factory, tmp_path):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_unplugged', plugged=False)
    try:
        rig = rig_factory({'devices': ['ams'], 'commands_allowed': True,
                           'commands_enabled': True, 'can.interface': 'slcan',
                           'can.channel': peer.channel, 'can.reconnect_period': 0.2,
                           'can.connect_wait': 8.0, 'can.options': ['sleep_after_open=0']},
                          wait_connected=False)
        calls = [rig.call_in_thread(Trigger, '/ams/start_charging') for _ in range(4)]
        rig.wait(lambda: rig.node.gate.bus_waiters() >= 1, 5.0, 'a call waiting')
        time.sleep(0.5)  # the four calls have reached the bridge
        ok, took = disarm(rig)
        assert ok and not rig.node.commands_enabled
        assert took < DISARM_BOUND, f'the disarm was answered after {took:.3f} s'
        # two waited for the bus (the gate's slots), the other two were refused at once
        answers = []
        for call in calls:
            call['thread'].join(5.0)
            answers.append(call['response'])
        assert sum('already wait for it' in a.message for a in answers) == 2, answers
        assert sum('commands_enabled was set to false while waiting' in a.message
                   for a in answers) == 2, answers
        assert not any(a.success for a in answers), answers
        # plugged in again: the bus opens, and nothing at all goes out (no START)
        peer.reopen()
        rig.wait(lambda: rig.node.can_io.status().connected, 10.0, 'the bus to open')
        time.sleep(0.5)
        assert peer.received() == [], peer.received()
        assert rig.failures == [], rig.failures
    finally:
        peer.shutdown()


def in_flight(rig, *ids: int) -> None:
    """Wait until the capture saw the first frame of each call (the call waits now)."""
    rig.wait(lambda: all(rig.capture.since(0, can_id) for can_id in ids), 5.0,
             'the calls in flight')


def test_deactivate_and_cleanup_end_an_ivt_s_read_config_waiting_for_its_answer(rig_factory):
    rig = rig_factory({'devices': ['ivt_s'], 'commands_allowed': True,
                       'commands_enabled': True, 'ivt_s.command_timeout': 20.0})
    pending = rig.call_in_thread(Trigger, '/ivt_s/read_config')  # no sensor: no answer
    in_flight(rig, IVT_COMMAND)
    started = time.monotonic()
    assert change(rig, Transition.TRANSITION_DEACTIVATE)
    assert time.monotonic() - started < 5.0
    pending['thread'].join(5.0)
    answer = pending['response']
    assert not answer.success and 'cancelled by deactivate' in answer.message, answer.message
    assert change(rig, Transition.TRANSITION_CLEANUP)
    # the node lives on: configure and activate again, the service answers again
    assert change(rig, Transition.TRANSITION_CONFIGURE)
    assert change(rig, Transition.TRANSITION_ACTIVATE)
    assert state(rig) == 'active'
    refused = rig.call(Trigger, '/ivt_s/read_config')  # armed only by a set: refused
    assert not refused.success and 'commands_enabled is false' in refused.message
    assert rig.failures == [], rig.failures
    assert rig.node.context.ok() and rig.executor._is_shutdown is False


def test_cleanup_ends_a_call_and_destroys_its_service_only_after_the_answer(rig_factory):
    rig = rig_factory({'devices': ['ivt_s', 'evms3'], 'commands_allowed': True,
                       'commands_enabled': True, 'ivt_s.command_timeout': 20.0,
                       'evms3.config_request': True, 'evms3.read_timeout': 20.0})
    ivt = rig.call_in_thread(Trigger, '/ivt_s/read_config')
    evms3 = rig.call_in_thread(Trigger, '/evms3/read_config')
    in_flight(rig, IVT_COMMAND, EVMS3_REQUEST)
    assert change(rig, Transition.TRANSITION_DEACTIVATE)
    assert change(rig, Transition.TRANSITION_CLEANUP)
    for pending in (ivt, evms3):
        pending['thread'].join(5.0)
        answer = pending['response']
        assert not answer.success and 'cancelled by deactivate' in answer.message, \
            answer.message
    assert change(rig, Transition.TRANSITION_CONFIGURE)
    assert rig.failures == [], rig.failures
    assert rig.executor._is_shutdown is False


def test_shutdown_from_active_ends_an_evms3_read_config_and_the_node_lives(rig_factory):
    rig = rig_factory({'devices': ['evms3'], 'commands_allowed': True,
                       'commands_enabled': True, 'evms3.config_request': True,
                       'evms3.read_timeout': 20.0})
    pending = rig.call_in_thread(Trigger, '/evms3/read_config')
    in_flight(rig, EVMS3_REQUEST)
    assert change(rig, Transition.TRANSITION_ACTIVE_SHUTDOWN)
    pending['thread'].join(5.0)
    answer = pending['response']
    assert not answer.success and 'cancelled by shutdown' in answer.message, answer.message
    assert state(rig) == 'finalized'
    assert rig.failures == [], rig.failures
    assert rig.executor._is_shutdown is False
