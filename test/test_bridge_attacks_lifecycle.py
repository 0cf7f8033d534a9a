# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Bad lifecycle and service requests against an armed bridge (issue 26, points 1 and 4).

Point 1: a ChangeState whose transition does not exist in the current state (configure sent
to an active bridge, an unknown id, an unknown label) is answered ``success: false``; the
bridge stays active and the armed AMS heartbeat goes on. Every request goes through the
real lifecycle service (``/ams_can_bridge/change_state``) from a client node.

Point 4: deactivate -> cleanup -> commands_enabled true (set while unconfigured) ->
configure gives an inactive bridge that sends nothing and publishes nothing, whatever the
parameters say; only activate arms it again.
"""
from __future__ import annotations

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState
from std_srvs.srv import Trigger

from ams_can_bridge.protocols.ams import DEFAULT_BASE_ID as AMS_BASE

NODE = '/ams_can_bridge'
HEARTBEAT = AMS_BASE + 5
ARMED = {'devices': ['ams'], 'commands_allowed': True, 'commands_enabled': True}
UNKNOWN_TRANSITION = 99  # no state of the rcl state machine has it


def state(rig) -> str:
    return rig.call(GetState, f'{NODE}/get_state').current_state.label


def change(rig, transition: int = 0, label: str = '') -> bool:
    return rig.call(ChangeState, f'{NODE}/change_state',
                    transition=Transition(id=transition, label=label)).success


def heartbeats_go_on(rig, count: int = 3) -> None:
    """Wait until the capture sees ``count`` more heartbeats than it had now."""
    mark = rig.capture.mark()
    rig.wait(lambda: len(rig.capture.since(mark, HEARTBEAT)) >= count, timeout=5.0,
             what=f'{count} more AMS heartbeats')


def test_a_transition_that_does_not_fit_the_state_is_refused_and_the_heartbeat_goes_on(
        rig_factory):
    rig = rig_factory(ARMED)
    heartbeats_go_on(rig)
    for transition, label in ((Transition.TRANSITION_CONFIGURE, ''),
                              (Transition.TRANSITION_CLEANUP, ''),
                              (Transition.TRANSITION_ACTIVATE, ''),
                              (UNKNOWN_TRANSITION, ''),
                              (0, 'no_such_transition')):
        assert not change(rig, transition, label), (transition, label)
        assert state(rig) == 'active'
        assert rig.node.commands_enabled
        heartbeats_go_on(rig)
    assert rig.failures == [], rig.failures
    assert rig.node.context.ok() and rig.executor._is_shutdown is False


def test_a_valid_transition_after_refused_ones_still_works(rig_factory):
    rig = rig_factory(ARMED)
    assert not change(rig, Transition.TRANSITION_CONFIGURE)
    assert change(rig, Transition.TRANSITION_DEACTIVATE)
    assert state(rig) == 'inactive' and not rig.node.commands_enabled
    assert change(rig, Transition.TRANSITION_ACTIVATE)
    assert state(rig) == 'active'
    assert rig.failures == [], rig.failures


BMS16_STATUS = 500  # primary: b0 error, b1 SoC %, b2..3 0.1 V LE, b4..5 0.1 A + 32768, b6 degC


def bms16_status(soc: int) -> bytes:
    """Return a BMS16 status frame (written by hand): SoC soc %, 51.0 V, 0.0 A, 22 degC."""
    return bytes([0x00, soc, 0xFE, 0x01, 0x00, 0x80, 0x16])


def set_through_service(rig, name: str, value) -> object:
    request = [Parameter(name, value=value).to_parameter_msg()]
    return rig.call(SetParameters, f'{NODE}/set_parameters', parameters=request).results[0]


def test_armed_while_unconfigured_then_configured_stays_silent_until_activated(rig_factory):
    rig = rig_factory({**ARMED, 'devices': ['ams', 'bms16']},
                      topics={'bms16/battery_state': BatteryState})
    node = rig.node
    heartbeats_go_on(rig)
    assert change(rig, Transition.TRANSITION_DEACTIVATE)
    assert change(rig, Transition.TRANSITION_CLEANUP)
    assert state(rig) == 'unconfigured'
    mark = rig.capture.mark()  # the bridge is the only sender on this channel from here

    result = set_through_service(rig, 'commands_enabled', True)
    assert not result.successful and 'unconfigured' in result.reason, result.reason
    assert node.get_parameter('commands_enabled').value is False
    assert change(rig, Transition.TRANSITION_CONFIGURE)
    assert state(rig) == 'inactive'
    rig.wait(lambda: node.can_io.status().connected, what='the bus to open')
    assert not node.commands_enabled and not node.devices['ams'].master.running
    result = set_through_service(rig, 'commands_enabled', True)
    assert not result.successful and 'inactive' in result.reason, result.reason
    answer = rig.call(Trigger, 'ams/enable_sc')
    assert not answer.success and 'commands_enabled' in answer.message
    rig.send(BMS16_STATUS, bms16_status(11))  # decoded, never published
    rig.wait(lambda: node.devices['bms16'].frames_received == 1, what='the frame decoded')
    rig.capture.sync()
    assert rig.capture.since(mark) == [], 'an inactive bridge sent frames'
    assert rig.frames_out() == 0

    assert change(rig, Transition.TRANSITION_ACTIVATE)  # the only way back
    rig.send(BMS16_STATUS, bms16_status(22))
    rig.wait(lambda: any(m.present and round(m.percentage * 100) == 22
                         for m in rig.messages('bms16/battery_state')),
             what='the frame published once active')
    published = [round(m.percentage * 100) for m in rig.messages('bms16/battery_state')
                 if m.present]
    assert 11 not in published, 'a frame taken while inactive was published'
    assert not node.commands_enabled  # activate does not arm what was refused
    assert rig.set_param('commands_enabled', True).successful
    heartbeats_go_on(rig)
    assert rig.failures == [], rig.failures
