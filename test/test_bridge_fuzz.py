# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Hostile traffic into the RUNNING bridge, over python-can's virtual bus and over slcan.

Hypothesis draws streams of frames at every ID the configured devices consume: random DLC
0..8 (0..64 on a CAN FD bus) and random data, remote frames, error frames (virtual bus),
mixed with valid status frames. An offline replica of the same devices (``DeviceSet``, as
log2bag builds it) sees the same frames and says which ones are malformed and which ones are
primary status frames.
After each stream, the running node must have:

- let nothing escape a callback, the executor or a thread (and no frame handler failed);
- published one present BatteryState per primary frame, each field NaN or in protocol range;
- counted in /diagnostics exactly the malformed (and error) frames that were sent;
- reflected the last valid frame (the stream's marker) in its newest message.
"""
from __future__ import annotations

import time

from hypothesis import given, settings, strategies as st
import pytest

from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.protocols.common import Frame
from command_rig import battery_topics, rigs
from conftest import examples
from helpers import unphysical
from slcan_peer import SlcanPeer
from shared import FRAMES

DEVICES = ['ams', 'ivt_s', 'evms3', 'bms16', 'sma']
PARAMS = {'devices': DEVICES, 'diagnostics_period': 0.1,
          'evms3.bms12_modules': 4, 'ams.bank_count': 3,  # their frames at more IDs
          # never stale during a test: every present message comes from a primary frame
          **{f'{d}.stale_timeout': 3600.0 for d in DEVICES}}
BMS16_STATUS = 500
CAN_ERR_BUSOFF = 0x40  # would make the bridge reopen the bus: bus faults are tested apart


def replica() -> DeviceSet:
    """Build the devices of PARAMS without ROS, exactly as the node builds its own."""
    return DeviceSet(DEVICES, lambda name, spec: PARAMS.get(name, spec.default))


IDS = replica().filters


def marker(soc: int) -> Frame:
    """Return a valid BMS16 status frame whose SoC identifies the end of a stream."""
    return Frame(BMS16_STATUS, bytes([0, soc, 0x0B, 0x02, 0x7D, 0x80, 25]))


FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def events(error_frames: bool, fd: bool = False):
    """Strategy: a stream of (kind, ...) events, kinds data / remote / valid / error."""
    known = st.sampled_from(IDS)
    payload = (st.sampled_from(FD_LENGTHS).flatmap(lambda n: st.binary(min_size=n, max_size=n))
               if fd else st.binary(max_size=8))
    kinds = [
        st.tuples(st.just('data'), known, payload),
        st.tuples(st.just('remote'), known, st.integers(0, 8)),
        st.tuples(st.just('valid'), st.sampled_from(FRAMES), st.just(b'')),
    ]
    if error_frames:
        kinds.append(st.tuples(st.just('error'),
                               st.integers(0, 0x1FFFFFFF).map(lambda e: e & ~CAN_ERR_BUSOFF),
                               st.binary(max_size=8)))
    return st.lists(st.one_of(kinds), min_size=1, max_size=40)


class Transport:
    """Sends frames to the bridge: its rig's virtual bus, or the adapter side of an slcan pty."""

    def __init__(self, kind: str, make, peer: SlcanPeer | None) -> None:
        self.kind = kind
        self.peer = peer
        params = dict(PARAMS)
        if peer is None:
            params['can.fd'] = kind == 'virtual-fd'
        else:
            params.update({'can.interface': 'slcan', 'can.channel': peer.channel,
                           'can.options': ['sleep_after_open=0']})
        self.bridge = make(params, topics=battery_topics(DEVICES))  # waits for the bus
        if peer is not None:
            peer.wait_open()

    def data(self, can_id: int, extended: bool, data: bytes) -> None:
        if self.peer is not None:
            assert self.peer.send(Frame(can_id, data, extended))
        else:
            self.bridge.send(can_id, data, extended, is_fd=len(data) > 8)

    def remote(self, can_id: int, extended: bool, dlc: int) -> None:
        if self.peer is not None:
            assert self.peer.send_remote(can_id, dlc, extended)
        else:
            self.bridge.send(can_id, b'', extended, is_remote_frame=True, dlc=dlc)

    def error(self, err_id: int, data: bytes) -> None:
        self.bridge.send(err_id, data, True, is_error_frame=True)


@pytest.fixture(scope='module', params=['virtual', 'virtual-fd', 'slcan'])
def live(request, tmp_path_factory):
    peer = (SlcanPeer(symlink=tmp_path_factory.mktemp('fuzz') / 'ttyACM_fuzz')
            if request.param == 'slcan' else None)
    try:
        with rigs() as make:  # what rig_factory yields, for the whole module
            transport = Transport(request.param, make, peer)
            transport.replica = replica()
            transport.errors_sent = 0
            transport.markers = 0
            yield transport
    finally:
        if peer is not None:
            peer.shutdown()


def run_stream(live: Transport, stream: list) -> None:
    bridge, devices = live.bridge, live.replica
    before = {d: bridge.present_count(f'{d}/battery_state') for d in DEVICES}
    expected = dict.fromkeys(DEVICES, 0)
    live.markers += 1
    soc = live.markers % 101
    stream = stream + [('valid', marker(soc), b'')]
    for kind, what, data in stream:
        if kind == 'error':
            live.error(what, data)
            live.errors_sent += 1
            continue
        if kind == 'remote':
            live.remote(what[0], what[1], data)
            continue
        frame = what if kind == 'valid' else Frame(what[0], data, what[1])
        live.data(frame.arbitration_id, frame.is_extended_id, frame.data)
        for device in devices.handle_frame(frame.arbitration_id, frame.data,
                                           frame.is_extended_id, time.time()):
            expected[device.name] += 1
    malformed = str(sum(d.frames_malformed for d in devices.devices.values()))

    def settled() -> bool:
        values = bridge.bus_values()
        return (all(bridge.present_count(f'{d}/battery_state') - before[d] == expected[d]
                    for d in DEVICES)
                and values.get('malformed frames') == malformed
                and (live.peer is not None
                     or values.get('error frames') == str(live.errors_sent)))
    try:
        bridge.wait(settled, 10, 'every primary frame published and every bad one counted')
    except AssertionError:
        got = {d: bridge.present_count(f'{d}/battery_state') - before[d] for d in DEVICES}
        raise AssertionError(f'published {got}, expected {expected}; diagnostics '
                             f'{bridge.bus_values()}, malformed expected {malformed}')
    assert bridge.failures == []
    assert bridge.node.can_io.status().callback_errors == 0
    with bridge.lock:
        new = {d: [m for m in bridge.msgs[f'{d}/battery_state'] if m.present][before[d]:]
               for d in DEVICES}
    for device, messages in new.items():
        for msg in messages:
            assert unphysical(msg) == [], (device, unphysical(msg))
    # the stream's last frame (a valid BMS16 status) is what the newest message says
    assert new['bms16'][-1].percentage == pytest.approx(soc / 100)


@settings(max_examples=examples(12))
@given(stream=st.data())
def test_hostile_streams_into_the_running_node(live, stream):
    run_stream(live, stream.draw(events(error_frames=live.peer is None,
                                        fd=live.kind == 'virtual-fd')))


def test_the_replica_is_not_vacuous():
    """The oracle really flags bad frames: a wrong DLC at every known ID is malformed."""
    devices = replica()
    primaries = 0
    for can_id, extended in IDS:
        primaries += len(devices.handle_frame(can_id, b'\x00' * 9, extended, time.time()))
    assert primaries == 0
    assert sum(d.frames_malformed for d in devices.devices.values()) >= len(IDS)
