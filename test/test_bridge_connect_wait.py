# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The connect race: a command issued while the bus is still opening waits for it.

python-can's slcan driver sleeps about 2 s while it opens the adapter (``sleep_after_open``)
and the bridge's services exist before that: a command called the moment its service
appears must succeed once the bus opens (within ``can.connect_wait``), and fail naming the
bus state and reason when it does not.
"""
from __future__ import annotations

from std_srvs.srv import Trigger

from ams_can_bridge.protocols.common import Frame
from helpers import wait_for
from slcan_peer import SlcanPeer

BMS16_RESET_SOC = 507
AMS_HEARTBEAT = 0x305
MARKER = Frame(0x7FF, b'\x01', False)  # no device's ID


def slcan(peer: SlcanPeer, **extra) -> dict:
    """Bridge parameters for the pty adapter, with python-can's own 2 s open delay."""
    params = {'can.interface': 'slcan', 'can.channel': peer.channel,
              'can.reconnect_period': 0.2, 'commands_allowed': True, 'commands_enabled': True}
    params.update(extra)
    return params


def test_command_called_as_its_service_appears_succeeds_once_the_bus_opens(
        rig_factory, tmp_path):
    with SlcanPeer(symlink=tmp_path / 'ttyACM_race') as peer:
        # ams.command_timeout bounds a state command in all, the wait for the bus included
        rig = rig_factory(slcan(peer, devices=['ams', 'bms16'], **{'ams.command_timeout': 5.0}),
                          wait_connected=False)
        assert rig.node.can_io.status().state == 'connecting'  # python-can still opening
        # one-shot AMS command (through the heartbeat) and a ZEVA command, both at once
        sync = rig.call_in_thread(Trigger, '/ams/sync_time')
        response = rig.call(Trigger, '/bms16/reset_soc')
        sync['thread'].join(10)
        assert response.success, response.message
        assert sync['response'].success, sync['response'].message
        # (an answer means written to the adapter; the peer reads the pty a moment later)
        wait_for(lambda: any(f.arbitration_id == BMS16_RESET_SOC for f in peer.received()),
                 5.0, 'the reset_soc frame at the adapter')
        # the heartbeat carried SYNC_TIME (6 in the low nibble of byte 0) exactly once
        synced = wait_for(lambda: [f for f in peer.received() if f.arbitration_id ==
                                   AMS_HEARTBEAT and f.data[0] & 0x0F == 6],
                          5.0, 'SYNC_TIME in a heartbeat at the adapter')
        assert len(synced) == 1, synced


def test_the_calls_really_raced_the_opening_bus(rig_factory, tmp_path):
    with SlcanPeer(symlink=tmp_path / 'ttyACM_zero') as peer:
        rig = rig_factory(slcan(peer, devices=['bms16'], **{'can.connect_wait': 0.0}),
                          wait_connected=False)
        response = rig.call(Trigger, '/bms16/reset_soc')
        # connect_wait 0: refused at once, while python-can still sleeps in its open
        assert not response.success
        assert 'not connected (connecting)' in response.message, response.message
        assert 'can.connect_wait is 0' in response.message
        assert 'nothing was sent' in response.message
        assert rig.node.can_io.status().state == 'connecting'
        # nothing was sent, and nothing kept for later: once the bus is open, a marker the
        # test sends through the bridge's bus is the first frame the adapter reads
        rig.wait(lambda: rig.node.can_io.status().connected, 10.0, 'the bus to open')
        rig.node.can_io.send(MARKER)
        assert peer.wait_received(1) == [MARKER]


def test_a_bus_that_does_not_open_fails_after_connect_wait_naming_state_and_reason(
        rig_factory, tmp_path):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_missing', plugged=False)
    rig = rig_factory(slcan(peer, devices=['ams', 'bms16'], **{
        'can.connect_wait': 0.3, 'ams.command_timeout': 0.2}), wait_connected=False)
    response = rig.call(Trigger, '/bms16/reset_soc')
    assert not response.success
    message = response.message
    assert 'not connected (error: ' in message and 'ttyACM_missing' in message, message
    assert 'after waiting 0.3 s (can.connect_wait 0.3 s)' in message, message
    # a state command keeps ams.command_timeout as its total bound
    response = rig.call(Trigger, '/ams/enable_ts')
    assert not response.success
    assert 'ENABLE_TS not sent' in response.message, response.message
    assert 'after waiting 0.2 s' in response.message and 'command timeout 0.2 s' in \
        response.message, response.message
    # plugged in later, the same call goes through
    peer.reopen()
    try:
        rig.node.can_io.wait_connected(5.0)
        rig.node.gate.connect_wait = 5.0
        response = rig.call(Trigger, '/bms16/reset_soc')
        assert response.success, response.message
        assert [f.arbitration_id for f in peer.wait_received(1)
                if f.arbitration_id == BMS16_RESET_SOC] == [BMS16_RESET_SOC]
    finally:
        peer.shutdown()


def test_installed_bridge_answers_a_command_called_as_soon_as_its_service_appears(tmp_path):
    """The report of issue 9, as a user hits it: installed bridge, slcan, call at once."""
    import os
    import subprocess

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_srvs.srv import SetBool

    from helpers import ros_context
    from executables import bridge_executable
    ns = f'race_{os.getpid()}'
    # The adapter is plugged in only after the calls were made, so they surely race the
    # opening bus; python-can then sleeps its own 2 s in the open (no sleep_after_open).
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_installed', plugged=False)
    with peer, ros_context() as context:
        params = tmp_path / 'race.yaml'
        params.write_text(
            '/**:\n  ros__parameters:\n    devices: [evms3, bms16]\n'
            '    commands_allowed: true\n    commands_enabled: true\n'
            f'    can: {{interface: slcan, channel: {peer.channel}, bitrate: 500000,'
            ' reconnect_period: 0.2, connect_wait: 10.0}\n')
        proc = subprocess.Popen(
            [bridge_executable(), '--ros-args', '-r', f'__ns:=/{ns}', '--params-file',
             str(params)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env=dict(os.environ))
        node = rclpy.create_node('race_client', context=context)
        try:
            setup = node.create_client(SetBool, f'/{ns}/evms3/set_setup_mode')
            reset = node.create_client(Trigger, f'/{ns}/bms16/reset_soc')
            assert setup.wait_for_service(timeout_sec=30) and reset.wait_for_service(30)
            futures = [setup.call_async(SetBool.Request(data=True)),
                       reset.call_async(Trigger.Request())]
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            executor.spin_once(timeout_sec=0.5)  # the requests are out and waiting
            assert not any(f.done() for f in futures)
            peer.reopen()  # plugged in
            for future in futures:
                executor.spin_until_future_complete(future, timeout_sec=15)
            executor.shutdown()
            answers = [f.result() for f in futures]
            assert all(a is not None and a.success for a in answers), answers
            ids = [f.arbitration_id for f in peer.wait_received(2)]
            assert 31 in ids and BMS16_RESET_SOC in ids, ids
        finally:
            node.destroy_node()
            proc.terminate()
            try:
                proc.communicate(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.communicate(timeout=10)
