# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""CanIo on real python-can buses: virtual in-process, slcan over a pty (SlcanPeer)."""
import logging
import sys
import threading
import time
import uuid

import can
import pytest

from ams_can_bridge.bus_state import BusStatus
from ams_can_bridge.can_io import BusConfig, CanIo, parse_options
from ams_can_bridge.errors import CanSendError
from ams_can_bridge.can_io.core import STATE_CHANGE_FORMAT
from ams_can_bridge.protocols.common import Frame

sys.path.insert(0, __file__.rsplit('/', 1)[0])
from helpers import wait_for  # noqa: E402, I100
from slcan_peer import SlcanPeer  # noqa: E402, I100


class Sink:
    """on_frame target that keeps what it got, thread-safely."""

    def __init__(self):
        self.frames = []
        self.lock = threading.Lock()

    def __call__(self, arbitration_id, data, extended, stamp):
        with self.lock:
            self.frames.append((arbitration_id, data, extended, stamp))

    def ids(self):
        with self.lock:
            return [(f[0], f[2]) for f in self.frames]


@pytest.fixture
def channel():
    return f'test_can_io_{uuid.uuid4().hex[:8]}'


@pytest.fixture
def peer_bus(channel):
    bus = can.Bus(interface='virtual', channel=channel)
    yield bus
    bus.shutdown()


def start_virtual(channel, sink, **kwargs):
    io = CanIo(BusConfig(interface='virtual', channel=channel, reconnect_period=0.1), sink,
               **kwargs)
    io.start()
    wait_for(lambda: io.status().state == 'connected', what='connected')
    return io


def test_parse_options_converts_obvious_types_and_names_bad_entries():
    assert parse_options(['sleep_after_open=0', 'timeout=0.5', 'rtscts=false', 'x=0x10',
                          'serial=010', 'name=can-a', 'listen_only=True']) == {
        'sleep_after_open': 0, 'timeout': 0.5, 'rtscts': False, 'x': 16, 'serial': 10,
        'name': 'can-a', 'listen_only': True}
    assert parse_options(None) == {}
    with pytest.raises(ValueError, match="'bitrate500000'"):
        parse_options(['bitrate500000'])
    with pytest.raises(ValueError, match="'=1'"):
        parse_options(['=1'])


def test_bus_config_rejects_bad_values_naming_the_field():
    with pytest.raises(ValueError, match='can.bitrate'):
        BusConfig(bitrate=-1)
    with pytest.raises(ValueError, match='can.reconnect_period'):
        BusConfig(reconnect_period=0)
    with pytest.raises(ValueError, match='can.replay_rate'):
        BusConfig(replay_rate=-1)
    assert BusConfig(interface='slcan', channel='/dev/ttyACM0').hardware_id == \
        'slcan:/dev/ttyACM0'
    # The ROS parameter form (string array) is accepted as is.
    assert BusConfig(options=['tty_baudrate=921600']).options == {'tty_baudrate': 921600}
    with pytest.raises(ValueError, match="'oops'"):
        BusConfig(options=['oops'])


def test_frames_in_with_receive_time_filters_and_counters(channel, peer_bus):
    sink = Sink()
    io = start_virtual(channel, sink, filters=[(0x100, False), (0x18FF50E5, True)])
    try:
        before = time.time()
        peer_bus.send(can.Message(arbitration_id=0x100, data=b'\x01\x02', is_extended_id=False))
        peer_bus.send(can.Message(arbitration_id=0x101, data=b'\x03', is_extended_id=False))
        # Same number, other ID space: must not pass the standard-ID filter.
        peer_bus.send(can.Message(arbitration_id=0x100, data=b'\x04', is_extended_id=True))
        peer_bus.send(can.Message(arbitration_id=0x18FF50E5, data=b'\x05',
                                  is_extended_id=True))
        peer_bus.send(can.Message(arbitration_id=0x100, is_remote_frame=True, dlc=2,
                                  is_extended_id=False))
        peer_bus.send(can.Message(arbitration_id=0x02, is_error_frame=True))
        wait_for(lambda: io.status().error_frames == 1, what='error frame counted')
        status = io.status()
        assert isinstance(status, BusStatus)
        assert status.state == 'connected'
        assert status.frames_in == 4          # data frames only (remote/error excluded)
        assert status.hardware_id == f'virtual:{channel}'
        assert [(f[0], f[1], f[2]) for f in sink.frames] == [
            (0x100, b'\x01\x02', False), (0x18FF50E5, b'\x05', True)]
        for _, data, _, stamp in sink.frames:
            assert isinstance(data, bytes)
            assert before - 1 <= stamp <= time.time() + 1
    finally:
        io.stop()


def test_no_filters_passes_everything(channel, peer_bus):
    sink = Sink()
    io = start_virtual(channel, sink)
    try:
        for i in range(5):
            peer_bus.send(can.Message(arbitration_id=0x200 + i, data=bytes([i]),
                                      is_extended_id=False))
        wait_for(lambda: len(sink.frames) == 5, what='5 frames')
        assert sink.ids() == [(0x200 + i, False) for i in range(5)]
    finally:
        io.stop()


def test_send_reaches_the_bus_and_is_counted(channel, peer_bus):
    io = start_virtual(channel, Sink())
    try:
        io.send(Frame(0x005, b'\x21\x07'))
        io.send(Frame(0x1F, b'\x01', True))
        first = peer_bus.recv(2.0)
        second = peer_bus.recv(2.0)
        assert (first.arbitration_id, bytes(first.data), first.is_extended_id) == \
            (0x005, b'\x21\x07', False)
        assert (second.arbitration_id, second.is_extended_id) == (0x1F, True)
        assert io.status().frames_out == 2
        with pytest.raises(CanSendError, match='invalid frame'):
            io.send(Frame(0x800, b'', False))   # 12 bits in an 11-bit ID
        assert io.status().frames_dropped_tx == 1
    finally:
        io.stop()


def test_send_when_not_connected_raises_clear_error():
    io = CanIo(BusConfig(interface='virtual', channel='x'), Sink())
    with pytest.raises(CanSendError, match='not connected'):
        io.send(Frame(0x100, b''))
    assert io.status().frames_dropped_tx == 1
    io.stop()   # never started: harmless
    assert io.status().state == 'stopped'


def test_stop_joins_the_thread_and_shuts_the_bus(channel, peer_bus):
    io = start_virtual(channel, Sink())
    io.stop()
    assert not [t for t in threading.enumerate() if t.name == 'can_io-rx' and t.is_alive()]
    assert io.status().state == 'stopped'
    with pytest.raises(CanSendError):
        io.send(Frame(0x100, b''))
    io.stop()   # twice is fine


def test_handler_exception_is_counted_and_receiving_goes_on(channel, peer_bus, caplog):
    got = []

    def handler(arbitration_id, data, extended, stamp):
        if data == b'\xff':
            raise ValueError('bad')
        got.append(arbitration_id)

    io = start_virtual(channel, handler)
    try:
        peer_bus.send(can.Message(arbitration_id=0x10, data=b'\xff', is_extended_id=False))
        peer_bus.send(can.Message(arbitration_id=0x11, data=b'\x00', is_extended_id=False))
        wait_for(lambda: got == [0x11], what='frame after the failing one')
        assert io.status().callback_errors == 1
        assert 'handler failed' in caplog.text
    finally:
        io.stop()


class StateLog(logging.Handler):
    """Every bus state CanIo reports through its logger, as (state, reason), in order."""

    def __init__(self):
        super().__init__()
        self.states = []

    def emit(self, record):
        if record.msg == STATE_CHANGE_FORMAT:
            _, state, reason = record.args
            self.states.append((state, reason))  # emit runs under the handler's lock

    def names(self):
        with self.lock:  # logging.Handler's own lock, the one emit runs under
            return [state for state, _ in self.states]


def test_bus_off_error_frame_reconnects_and_error_passive_is_reported(channel, peer_bus):
    states = StateLog()
    logger = logging.getLogger(f'test_can_io.bus_off.{channel}')
    logger.propagate = False
    logger.setLevel(logging.DEBUG)
    logger.addHandler(states)
    io = start_virtual(channel, Sink(), logger=logger)
    try:
        # SocketCAN encoding: CAN_ERR_CRTL with data[1] = TX passive.
        peer_bus.send(can.Message(arbitration_id=0x04, is_error_frame=True,
                                  data=b'\x00\x20\x00\x00\x00\x00\x00\x00'))
        wait_for(lambda: io.status().state == 'error-passive', what='error-passive')
        assert 'error-passive' in io.status().reason
        peer_bus.send(can.Message(arbitration_id=0x04, is_error_frame=True,
                                  data=b'\x00\x40\x00\x00\x00\x00\x00\x00'))
        wait_for(lambda: io.status().state == 'connected', what='back to active')
        peer_bus.send(can.Message(arbitration_id=0x40, is_error_frame=True))
        wait_for(lambda: io.status().reconnects == 1, what='reconnect after bus-off')
        wait_for(lambda: io.status().state == 'connected', what='connected again')
        assert io.status().error_frames == 3
        names = states.names()
        # active -> passive -> active -> bus-off -> re-opened, each reported in this order
        assert names == ['connecting', 'connected', 'error-passive', 'connected', 'bus-off',
                         'connected'], names
        bus_off_reason = dict(states.states)['bus-off']
        assert 'bus-off' in bus_off_reason, bus_off_reason
    finally:
        io.stop()


def test_unknown_interface_is_an_error_state_not_an_exception():
    io = CanIo(BusConfig(interface='no_such_interface', channel='x', reconnect_period=0.1),
               Sink())
    io.start()
    try:
        wait_for(lambda: io.status().state == 'error', what='error state')
        assert 'no_such_interface' in io.status().reason
    finally:
        io.stop()


def test_a_burst_of_20000_frames_arrives_complete(channel, peer_bus):
    """A queue filled faster than it is drained loses nothing (rate: bench/)."""
    seen = []
    io = start_virtual(channel, lambda i, d, e, t: seen.append(i),
                       filters=[(0x100 + i, False) for i in range(40)])
    try:
        n = 20000
        for i in range(n):
            peer_bus.send(can.Message(arbitration_id=0x100 + i % 40, data=bytes(8),
                                      is_extended_id=False))
        wait_for(lambda: len(seen) == n, timeout=30, what='all frames')
        assert io.status().frames_in == n
        assert seen == [0x100 + i % 40 for i in range(n)]  # in order
    finally:
        io.stop()


def test_slcan_channel_missing_at_start_then_appears(tmp_path, capfd, caplog):
    caplog.set_level(logging.INFO)
    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN0', plugged=False)
    sink = Sink()
    io = CanIo(BusConfig(interface='slcan', channel=peer.channel, bitrate=500000,
                         options={'sleep_after_open': 0}, reconnect_period=0.1), sink)
    io.start()
    try:
        wait_for(lambda: io.status().state == 'error', what='error state')
        assert 'ttyCAN0' in io.status().reason
        peer.reopen()
        peer.wait_open()
        wait_for(lambda: io.status().state == 'connected', what='connected')
        assert peer.bitrate_command == 'S6'
        assert io.status().reconnects == 0   # a first connection is not a reconnect
        peer.send(Frame(0x123, b'\x01\x02'))
        peer.send(Frame(0x1234567, b'\xAA', True))
        wait_for(lambda: len(sink.frames) == 2, what='frames from the adapter')
        assert sink.ids() == [(0x123, False), (0x1234567, True)]
        io.send(Frame(0x321, b'\xBE\xEF'))
        assert peer.wait_received(1) == [Frame(0x321, b'\xBE\xEF', False)]
        io.stop()
        # python-can closes the CAN channel ('C') before the port on a clean shutdown.
        wait_for(lambda: peer.commands[-1] == 'C', what='close command')
        assert not peer.is_open
    finally:
        io.stop()
        peer.close()
    assert 'Traceback' not in capfd.readouterr().err
    assert 'Traceback' not in caplog.text


def test_slcan_unplugged_mid_run_reconnects_alone(tmp_path, capfd, caplog):
    caplog.set_level(logging.INFO)
    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN0')
    sink = Sink()
    io = CanIo(BusConfig(interface='slcan', channel=peer.channel,
                         options={'sleep_after_open': 0}, reconnect_period=0.1), sink)
    io.start()
    try:
        peer.wait_open()
        wait_for(lambda: io.status().state == 'connected', what='connected')
        peer.send(Frame(0x100, b'\x01'))
        wait_for(lambda: len(sink.frames) == 1, what='first frame')
        peer.close()                                    # unplugged
        wait_for(lambda: io.status().state == 'reconnecting', what='reconnecting')
        with pytest.raises(CanSendError, match='not connected'):
            io.send(Frame(0x100, b''))
        peer.reopen()                                   # plugged back in
        peer.wait_open()
        wait_for(lambda: io.status().state == 'connected', what='reconnected')
        assert io.status().reconnects == 1
        peer.send(Frame(0x101, b'\x02'))
        wait_for(lambda: len(sink.frames) == 2, what='frame after reconnect')
        assert sink.ids()[-1] == (0x101, False)
    finally:
        io.stop()
        peer.close()
    assert 'reconnecting' in caplog.text
    assert 'Traceback' not in capfd.readouterr().err
    assert 'Traceback' not in caplog.text


def test_second_bus_on_the_same_serial_adapter_is_refused_and_the_first_undisturbed(
        tmp_path, monkeypatch, capfd, caplog):
    """Issue 18.3: the port is opened exclusively; the second user is told about slcand."""
    from ams_can_bridge.can_io import slcan
    attempts = []
    real_lock = slcan.lock_serial_port

    def counting_lock(channel):
        attempts.append(channel)
        return real_lock(channel)

    monkeypatch.setattr(slcan, 'lock_serial_port', counting_lock)
    caplog.set_level(logging.INFO)
    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN0')
    first_sink, second_sink = Sink(), Sink()
    config = dict(interface='slcan', channel=peer.channel, bitrate=500000,
                  options={'sleep_after_open': 0}, reconnect_period=0.05)
    first = CanIo(BusConfig(**config), first_sink)
    second = CanIo(BusConfig(**config), second_sink)
    first.start()
    try:
        peer.wait_open()
        wait_for(lambda: first.status().state == 'connected', what='first connected')
        first.send(Frame(0x7FF, b''))  # a round trip: the peer has read all the opening
        peer.wait_received(1)
        commands = list(peer.commands)
        second.start()
        wait_for(lambda: second.status().state == 'error', what='second refused')
        reason = second.status().reason
        assert f'serial port {peer.channel} is in use' in reason
        assert 'slcand' in reason and 'can.interface: socketcan' in reason
        # it keeps retrying (each try only asks for the lock), and the adapter never hears it
        seen = len(attempts)
        wait_for(lambda: len(attempts) >= seen + 3, what='three more attempts')
        assert second.status().state == 'error'
        assert peer.commands == commands
        for i in range(20):
            peer.send(Frame(0x100 + i, bytes([i])))
        wait_for(lambda: len(first_sink.frames) == 20, what='frames to the first')
        assert first_sink.ids() == [(0x100 + i, False) for i in range(20)]
        assert second_sink.frames == []
        first.send(Frame(0x321, b'\xBE\xEF'))
        assert peer.wait_received(2)[1:] == [Frame(0x321, b'\xBE\xEF', False)]
        assert peer.commands == commands  # the first's frame came next: none of the second's
        assert first.status().frames_unreadable == 0 and first.status().reconnects == 0
        # the first lets go of the adapter: the second takes it at its next attempt
        first.stop()
        wait_for(lambda: second.status().state == 'connected', what='second connected')
    finally:
        first.stop()
        second.stop()
        peer.close()
    assert 'Traceback' not in capfd.readouterr().err


def test_a_stop_that_gives_up_its_join_never_leaves_two_receive_threads(channel, monkeypatch):
    """stop() waits for the thread a bounded time; a later start() never runs a second."""
    import ams_can_bridge.can_io.core as core
    from ams_can_bridge.errors import CanIoError
    monkeypatch.setattr(core, '_JOIN_TIMEOUT', 0.2)
    io = CanIo(BusConfig(interface='virtual', channel=channel, reconnect_period=0.05),
               Sink())
    entered, release = threading.Event(), threading.Event()
    original = io._open
    calls = []

    def hanging_open():  # the first open hangs in its driver until released
        calls.append(threading.current_thread())
        if len(calls) == 1:
            entered.set()
            release.wait(timeout=10.0)
        return original()
    io._open = hanging_open
    io.start()
    assert entered.wait(timeout=5.0)
    first = io._thread
    io.stop()  # gives up after 0.2 s: the open hangs
    assert first.is_alive()
    with pytest.raises(CanIoError, match='previous receive thread'):
        io.start()
    release.set()
    first.join(timeout=5.0)
    assert not first.is_alive(), 'the old thread must end once its open returns'
    io.start()
    try:
        assert wait_for(lambda: io.status().connected, 5.0)
        readers = [t for t in threading.enumerate() if t.name == 'can_io-rx' and t.is_alive()]
        assert readers == [io._thread]
    finally:
        io.stop()
