"""
The connect race: a command issued while the bus is still opening waits for it.

python-can's slcan driver sleeps about 2 s while it opens the adapter (``sleep_after_open``)
and the bridge's services exist before that: a command called the moment its service
appears must succeed once the bus opens (within ``can.connect_wait``), and fail naming the
bus state and reason when it does not.
"""
from __future__ import annotations

import pytest
from std_srvs.srv import Trigger

from command_rig import rigs
from slcan_peer import SlcanPeer

BMS16_RESET_SOC = 507
AMS_HEARTBEAT = 0x305


@pytest.fixture
def rig_factory():
    with rigs() as make:
        yield make


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
        frames = peer.wait_received(1)
        assert any(f.arbitration_id == BMS16_RESET_SOC for f in frames)
        # the heartbeat carried SYNC_TIME (6 in the low nibble of byte 0) exactly once
        synced = [f for f in peer.wait_received(1)
                  if f.arbitration_id == AMS_HEARTBEAT and f.data[0] & 0x0F == 6]
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
        assert peer.received() == []


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
        rig.node.connect_wait = 5.0
        response = rig.call(Trigger, '/bms16/reset_soc')
        assert response.success, response.message
        assert [f.arbitration_id for f in peer.wait_received(1)
                if f.arbitration_id == BMS16_RESET_SOC] == [BMS16_RESET_SOC]
    finally:
        peer.shutdown()
