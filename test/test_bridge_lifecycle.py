# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge as a lifecycle node, driven through the lifecycle_msgs services (autostart false).

unconfigured: nothing open. configure: parameters checked, devices built, bus open, frames
decoded, nothing published, nothing sent (commands_enabled given at launch waits for
activate). activate: publishing, and the AMS heartbeat once armed. deactivate: a pure
listener again (commands forced off). cleanup: bus closed, receive thread joined, command
services and publishers gone; configure works again. shutdown: finalized.
"""
from __future__ import annotations

import gc
import threading

from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState, GetState

from ams_can_bridge.protocols.ams import DEFAULT_BASE_ID as AMS_BASE
from helpers import assert_ended

NODE = '/ams_can_bridge'
BMS16_STATUS = 500  # primary: b0 error, b1 SoC %, b2..3 0.1 V LE, b4..5 0.1 A + 32768, b6 degC


def status(soc: int) -> bytes:
    """Return a BMS16 status frame (written by hand): SoC soc %, 51.0 V, 0.0 A, 22 degC."""
    return bytes([0x00, soc, 0xFE, 0x01, 0x00, 0x80, 0x16])


def state(rig) -> str:
    return rig.call(GetState, f'{NODE}/get_state').current_state.label


def change(rig, transition: int) -> bool:
    return rig.call(ChangeState, f'{NODE}/change_state',
                    transition=Transition(id=transition)).success


def socs(rig) -> list[int]:
    return [round(m.percentage * 100) for m in rig.messages('bms16/battery_state')
            if m.present]


def receivers() -> int:
    return sum(1 for t in threading.enumerate() if t.name == 'can_io-rx' and t.is_alive())


def test_configure_activate_deactivate_cleanup_through_the_lifecycle_services(rig_factory):
    from sensor_msgs.msg import BatteryState
    rig = rig_factory({'autostart': False, 'devices': ['bms16', 'ams'],
                       'commands_allowed': True, 'commands_enabled': True},
                      topics={'bms16/battery_state': BatteryState}, wait_connected=False)
    node = rig.node
    heartbeat = AMS_BASE + 5
    assert state(rig) == 'unconfigured'
    assert node.can_io is None and not node.command_services

    gc.unfreeze()
    assert change(rig, Transition.TRANSITION_CONFIGURE)
    assert state(rig) == 'inactive'
    # what configure built is kept out of full collections (a pause of every thread)
    assert gc.get_freeze_count() > 0
    rig.wait(lambda: node.can_io.status().connected, what='the bus to open')
    # armed at launch, but inactive: the gate is shut and the heartbeat does not run
    assert node.commands_enabled is False
    assert node.get_parameter('commands_enabled').value is False
    assert not node.devices['ams'].master.running
    rig.assert_silent_since(0)  # a marker: nothing was sent while inactive
    assert not rig.set_param('commands_enabled', True).successful
    rig.send(BMS16_STATUS, status(11))  # decoded, not published
    rig.wait(lambda: node.devices['bms16'].frames_received == 1, what='the frame decoded')

    assert change(rig, Transition.TRANSITION_ACTIVATE)
    assert state(rig) == 'active'
    assert node.commands_enabled is True  # the launch value applies once active
    mark = rig.capture.mark()
    rig.wait(lambda: rig.capture.since(mark, heartbeat), what='the AMS heartbeat')
    rig.send(BMS16_STATUS, status(22))
    rig.wait(lambda: 22 in socs(rig), what='the frame published')

    heartbeat = node.devices['ams'].master.thread
    assert change(rig, Transition.TRANSITION_DEACTIVATE)
    frames_out = rig.frames_out()
    assert state(rig) == 'inactive'
    assert node.commands_enabled is False and not node.devices['ams'].master.running
    # a pure listener: the heartbeat's thread has ended, nothing after deactivate returned
    assert_ended(heartbeat, 'the heartbeat')
    rig.assert_silent_since(frames_out)
    assert node.get_parameter('commands_enabled').value is False
    rig.send(BMS16_STATUS, status(33))  # decoded, not published
    rig.wait(lambda: node.devices['bms16'].frames_received == 3, what='the frame decoded')
    assert change(rig, Transition.TRANSITION_ACTIVATE)
    rig.send(BMS16_STATUS, status(44))
    rig.wait(lambda: 44 in socs(rig), what='the frame published')
    assert socs(rig) == [22, 44], 'a frame taken while inactive was published'
    assert node.commands_enabled is False  # disarmed by deactivate: stays so

    assert change(rig, Transition.TRANSITION_DEACTIVATE)
    assert change(rig, Transition.TRANSITION_CLEANUP)
    assert state(rig) == 'unconfigured'
    assert node.can_io is None and not node.command_services and receivers() == 0
    assert node.count_publishers('bms16/battery_state') == 0

    assert change(rig, Transition.TRANSITION_CONFIGURE)  # again, with the same parameters
    assert state(rig) == 'inactive' and receivers() == 1
    assert change(rig, Transition.TRANSITION_INACTIVE_SHUTDOWN)
    assert state(rig) == 'finalized'
    assert node.can_io is None and receivers() == 0


def test_a_bad_value_fails_configure_and_leaves_it_unconfigured(rig_factory):
    rig = rig_factory({'autostart': False, 'devices': ['bms16'], 'bms16.base_id': -4},
                      wait_connected=False)
    assert state(rig) == 'unconfigured'
    assert not change(rig, Transition.TRANSITION_CONFIGURE)
    assert state(rig) == 'unconfigured'
    assert rig.node.can_io is None


def test_a_destroyed_bridge_frees_its_participant():
    """Free the DDS participant: rclpy's state machine kept every destroyed one open."""
    import os
    from command_rig import Rig

    def fds() -> int:
        return len(os.listdir('/proc/self/fd'))
    Rig({'devices': ['bms16']}).close()  # the first one loads what stays loaded
    before = fds()
    for _ in range(3):
        Rig({'devices': ['bms16']}).close()
    assert fds() <= before + 2, f'{fds() - before} file descriptors left by 3 bridges'
