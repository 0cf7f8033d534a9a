# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A newcomer's first hour without papercuts (issue 31 point 5): each found by trying the package.

Each test makes the newcomer's move and checks what the bridge says or does now: a ``-p``
rcl dropped, slcan without a bit rate, a machine without SocketCAN, the launch file without
a params file, two bridges of one name, a state command's silent wait, the heartbeat started
before the slcan adapter is open, the channel of a recording, a replay that never ends.
"""
from __future__ import annotations

import errno
import itertools
import math
import os
from pathlib import Path
import signal
import socket
import subprocess
import threading
import time

import can
from diagnostic_msgs.msg import DiagnosticArray
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState
from std_srvs.srv import Trigger

from ams_can_bridge.bus_state import BusState
from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.can_io.config import SLCAN_NO_BITRATE
from ams_can_bridge.can_io.core import _open_failure
from ams_can_bridge.devices.base import Level
from ams_can_bridge.engine.startup import bus_settings, name_collision
from ams_can_bridge.errors import CanSendError
from ams_can_bridge.parameters import BUS_PARAMS
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.reports import bus_report
from ams_can_bridge.ros.bridge_node import BridgeNode
from ams_can_bridge.ros.overrides import rcl_value, unapplied_overrides
from executables import bridge_executable
from helpers import ros_context, wait_for
from slcan_peer import SlcanPeer

_ids = itertools.count()
BUS = {spec.key: spec.default for spec in BUS_PARAMS}
# BMS16 status (doc/protocols.md, as test_bridge_slcan's): byte 1 is the SoC in %
BMS16_STATUS = bytes([0, 81, 0x0B, 0x02, 0x7D, 0x80, 25])


def has_socketcan() -> bool:
    """Tell whether this kernel has the CAN address family (SocketCAN) at all."""
    try:
        socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
    except OSError as exc:
        if exc.errno == errno.EAFNOSUPPORT:
            return False
    return True


class Bridge:
    """The installed bridge as a process; its output collected line by line."""

    def __init__(self, *args: str) -> None:
        self.proc = subprocess.Popen([bridge_executable(), '--ros-args', *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, env=dict(os.environ))
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)

    @property
    def output(self) -> str:
        return ''.join(self.lines)

    def wait_line(self, text: str, timeout: float = 30.0) -> None:
        wait_for(lambda: text in self.output, timeout, f'{text!r} in {self.output!r}')

    def stop(self) -> int:
        """SIGINT, then the exit code (killed after 20 s)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            code = self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait(timeout=10)
        self._reader.join(timeout=5)
        return code


def params(tmp_path: Path, body: str) -> str:
    path = tmp_path / f'params_{next(_ids)}.yaml'
    path.write_text('/**:\n  ros__parameters:\n' + body)
    return str(path)


def virtual(tag: str) -> str:
    return f'    can: {{interface: virtual, channel: first_hour_{tag}_{os.getpid()}}}\n'


# --- 1: a -p value rcl dropped stops the bridge, naming it --------------------------------
def test_a_p_value_rcl_drops_stops_the_bridge_naming_it(tmp_path):
    path = params(tmp_path, '    devices: [bms16]\n    can: {interface: virtual, '
                  f'channel: first_hour_p_{os.getpid()}, bitrate: 250000}}\n')
    run = [bridge_executable(), '--ros-args']
    typed = subprocess.run(run + ['--params-file', path, '-p', 'can.bitrate:=500k'],
                           capture_output=True, text=True, timeout=30, env=dict(os.environ))
    assert typed.returncode == 2, typed.stderr
    assert ('cannot start: -p can.bitrate:=500k was not applied: the node got can.bitrate = '
            "250000 from the params file, as rcl drops a -p value of another type than the "
            "file's (a string here, an integer there) without a word: write it as an "
            'integer') in typed.stderr, typed.stderr
    assert 'Traceback' not in typed.stderr
    before = subprocess.run(run + ['-p', 'can.bitrate:=500000', '--params-file', path],
                            capture_output=True, text=True, timeout=30, env=dict(os.environ))
    assert before.returncode == 2, before.stderr
    assert ('-p can.bitrate:=500000 was not applied: the node got can.bitrate = 250000 from '
            'a --params-file given after it: put -p after --params-file') in before.stderr


def test_the_p_values_are_typed_as_rcl_types_them():
    """The bridge reads the command line as rcl itself types each value."""
    texts = ['2', '500k', '0x10', '010', '-3', '+7', 'nan', '.inf', '-.Inf', '1e3', '1.5',
             'Y', 'off', 'True', '"5"', "'x'", '!!str 5', '1_000', '[1, 2]', '[1.5, 2.5]',
             '[a, b]', '[true, false]', 'can0', '/dev/ttyACM0', '9223372036854775808']
    args = ['bridge', '--ros-args']
    for i, text in enumerate(texts):
        args += ['-p', f'v{i}:={text}']
    context = Context()
    rclpy.init(args=args, context=context)
    try:
        node = rclpy.create_node('typing', context=context)
        got = {name: p.value for name, p in node._parameter_overrides.items()}
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    for i, text in enumerate(texts):
        ours, rcl = rcl_value(text), got[f'v{i}']
        if isinstance(rcl, list):
            assert [type(v) for v in ours] == [type(v) for v in rcl] and ours == rcl, text
        elif isinstance(rcl, float) and math.isnan(rcl):
            assert isinstance(ours, float) and math.isnan(ours), text
        else:
            assert type(ours) is type(rcl) and ours == rcl, (text, ours, rcl)
    # and every one of them arrived as given: nothing to report
    assert unapplied_overrides(args, '/typing', got) == []


def test_only_the_bridges_p_values_are_compared():
    argv = ['bridge', '--ros-args', '-p', 'other_node:can.bitrate:=x', '-p',
            'ams_can_bridge:diagnostics_period:=2', '--', '-p', 'can.fd:=1']
    assert unapplied_overrides(argv, '/ams_can_bridge', {
        'can.bitrate': 500000, 'diagnostics_period': 1.0, 'can.fd': True}) == [
        '-p diagnostics_period:=2 was not applied: the node got diagnostics_period = 1.0 '
        "from the params file, as rcl drops a -p value of another type than the file's (an "
        'integer here, a decimal number there) without a word: write it as a decimal number '
        '(e.g. 2.0, not 2)']


# --- 2: slcan without a bit rate ----------------------------------------------------------
def test_slcan_without_a_bitrate_warns_at_start():
    settings = bus_settings({**BUS, 'interface': 'slcan', 'channel': '/dev/ttyACM0'})
    assert settings.errors == [] and settings.warnings == [SLCAN_NO_BITRATE]
    assert 'set can.bitrate' in SLCAN_NO_BITRATE
    set_rate = bus_settings({**BUS, 'interface': 'slcan', 'channel': '/dev/ttyACM0',
                             'bitrate': 500000})
    assert set_rate.warnings == []
    assert bus_settings({**BUS, 'interface': 'virtual', 'channel': 'x'}).warnings == []


def test_the_bridge_logs_the_slcan_bitrate_warning(tmp_path):
    with SlcanPeer(symlink=tmp_path / 'ttyACM_rate') as peer:
        bridge = Bridge('--params-file', params(
            tmp_path, f'    can: {{interface: slcan, channel: {peer.channel}, '
            'options: [sleep_after_open=0]}\n'), '-r', f'__node:=first_hour_rate_{os.getpid()}')
        try:
            bridge.wait_line('connected')
        finally:
            code = bridge.stop()
        assert code == 0, bridge.output
        assert peer.bitrate_command == ''  # nothing was set: hence the warning
    [line] = [line for line in bridge.lines if 'can.bitrate is 0 with slcan' in line]
    assert line.startswith('[WARN]'), line


# --- 3: a machine without SocketCAN -------------------------------------------------------
def test_no_socketcan_is_named_with_what_to_use_instead():
    reason = _open_failure('socketcan', OSError(errno.EAFNOSUPPORT,
                                                'Address family not supported by protocol'))
    assert reason.startswith('this machine has no SocketCAN ([Errno 97] Address family not '
                             'supported by protocol: '), reason
    for advice in ('modprobe can', 'slcan', 'virtual'):
        assert advice in reason, reason
    # another failure of socketcan (no such adapter) is python-can's own reason
    assert _open_failure('socketcan', OSError(errno.ENODEV, 'No such device')) == \
        '[Errno 19] No such device'


@pytest.mark.skipif(has_socketcan(), reason='this machine has SocketCAN: the real refusal '
                    'cannot happen here (the reason itself is tested above)')
def test_the_default_socketcan_on_this_machine_says_so_in_the_log_and_diagnostics(tmp_path):
    io = CanIo(BusConfig(interface='socketcan', channel='can0', reconnect_period=0.2),
               lambda *frame: None)
    io.start()
    try:
        status = wait_for(lambda: (lambda s: s if s.reason else None)(io.status()),
                          what='the open to fail')
    finally:
        io.stop()
    assert status.state == BusState.ERROR
    report = bus_report(status, 0, 'socketcan')
    assert report.level == Level.ERROR
    assert 'this machine has no SocketCAN' in report.message, report.message
    # the bridge itself, as a newcomer starts it: no params file, the default interface
    bridge = Bridge('-r', f'__node:=first_hour_socketcan_{os.getpid()}')
    try:
        bridge.wait_line('this machine has no SocketCAN')
    finally:
        code = bridge.stop()
    assert code == 0, bridge.output
    [line] = [line for line in bridge.lines if 'has no SocketCAN' in line]
    assert line.startswith('[ERROR]') and 'cannot be opened' in line, line
    assert 'can.interface: slcan' in line and 'virtual' in line, line


# --- 5: two bridges of one name -----------------------------------------------------------
def test_a_second_bridge_of_the_same_name_warns_naming_the_fix(tmp_path):
    twin = f'first_hour_twin_{os.getpid()}'
    first = Bridge('--params-file', params(tmp_path, virtual('twin_a')), '-r', f'__node:={twin}')
    single = Bridge('--params-file', params(tmp_path, virtual('single')),
                    '-r', f'__node:=first_hour_single_{os.getpid()}')
    second = None
    try:
        first.wait_line('connected')
        single.wait_line('connected')
        second = Bridge('--params-file', params(tmp_path, virtual('twin_b')),
                        '-r', f'__node:={twin}')
        second.wait_line(f'another node is named /{twin} on this ROS graph', timeout=20)
    finally:
        codes = [b.stop() for b in (first, single, second) if b is not None]
    assert codes == [0, 0, 0], second.output if second else first.output
    [line] = [line for line in second.lines if 'another node is named' in line]
    assert line.startswith('[WARN]')
    assert '-r __node:=bridge_can1' in line and '-r __ns:=/car2' in line, line
    assert 'another node is named' not in single.output, single.output


def test_the_name_check_counts_only_this_nodes_name_and_namespace():
    graph = [('ams_can_bridge', '/'), ('ams_can_bridge', '/car2'), ('probe', '/')]
    assert name_collision(graph, 'ams_can_bridge', '/') is None
    warning = name_collision(graph + [('ams_can_bridge', '/car2')], 'ams_can_bridge', '/car2')
    assert warning is not None
    assert 'another node is named /car2/ams_can_bridge' in warning
    assert "'car2/ams_can_bridge: CAN bus'" in warning


# --- 6: a state command says when the heartbeat carries it ---------------------------------
def test_a_state_command_is_logged_when_carried_and_when_answered(rig_factory, capfd):
    rig = rig_factory({'devices': ['ams'], 'commands_allowed': True, 'commands_enabled': True,
                       'ams.heartbeat_period': 0.02, 'ams.command_timeout': 1.5})
    capfd.readouterr()
    call = rig.call_in_thread(Trigger, '/ams/enable_sc')  # no AMS: it waits 1.5 s
    seen: list[str] = []

    def carried() -> bool:
        seen.append(capfd.readouterr().err)
        return 'ENABLE_SC carried in the heartbeat' in ''.join(seen)
    wait_for(carried, 1.0, 'the carried line (well before the answer)')
    assert 'response' not in call  # logged while the call still waits
    call['thread'].join(5.0)
    assert not call['response'].success
    seen.append(capfd.readouterr().err)
    lines = [line for line in ''.join(seen).splitlines() if '[ams_can_bridge]' in line]
    [carry] = [line for line in lines if 'carried in the heartbeat' in line]
    assert carry.startswith('[INFO]'), carry
    assert 'ams: ENABLE_SC carried in the heartbeat from counter ' in carry, carry
    assert 'waiting for SC_ENABLED (up to 1.' in carry, carry
    answer = [i for i, line in enumerate(lines) if 'ams/enable_sc: answered' in line]
    assert answer and lines.index(carry) < answer[0], lines


# --- 7: the periodic senders start when the bus is connected --------------------------------
def test_senders_armed_at_launch_start_when_the_slcan_bus_opens(tmp_path):
    """An slcan adapter opens late: nothing may be sent, nor dropped, meanwhile."""
    with SlcanPeer(symlink=tmp_path / 'ttyACM_armed') as peer, ros_context() as context:
        node = BridgeNode(context=context, namespace=f'first_hour_armed_{os.getpid()}',
                          parameter_overrides=[Parameter(k, value=v) for k, v in {
                              'can.interface': 'slcan', 'can.channel': peer.channel,
                              'can.bitrate': 500000,
                              'can.options': ['sleep_after_open=1.0'],
                              'commands_allowed': True, 'commands_enabled': True,
                              'devices': ['ams', 'sma'], 'ams.base_id': 0x400,
                              'ams.heartbeat_period': 0.05,
                              'sma.inverter_keepalive': True}.items()])
        try:
            assert not node.can_io.status().connected  # python-can sleeps before it opens
            assert not node.devices['ams'].master.running
            peer.wait_open(timeout=10)
            wait_for(lambda: len([f for f in peer.received()
                                  if f.arbitration_id == 0x405]) >= 5, 5.0, 'heartbeats')
            wait_for(lambda: any(f.arbitration_id == 0x305 for f in peer.received()), 5.0,
                     'the inverter keep-alive')
            status = node.can_io.status()
            heartbeats = [f for f in peer.received() if f.arbitration_id == 0x405]
            keepalive = node.devices['sma'].keepalive
        finally:
            node.destroy_node()
    assert status.frames_dropped_tx == 0, status
    assert heartbeats[0].data[1] == 0  # the first heartbeat is counter 0: none was lost
    assert keepalive.failed == 0, keepalive.last_error
    assert bus_report(status, 0, 'slcan').level == Level.OK


def test_a_frame_dropped_on_a_connected_bus_is_a_warn_naming_it():
    channel = f'first_hour_drop_{os.getpid()}'
    io = CanIo(BusConfig(interface='virtual', channel=channel), lambda *frame: None)
    io.start()
    try:
        wait_for(lambda: io.status().connected, what='the virtual bus')
        assert bus_report(io.status(), 0, 'virtual').level == Level.OK
        with pytest.raises(CanSendError):
            io.send(Frame(0x123, bytes(65)))  # 65 bytes: no CAN frame, not even FD
        status = io.status()
    finally:
        io.stop()
    assert status.connected and status.frames_dropped_tx == 1
    report = bus_report(status, 0, 'virtual')
    assert report.level == Level.WARN
    assert report.message.startswith('connected; 1 frames dropped (tx), the last 0.'), \
        report.message
    assert 'invalid frame' in report.message and 'invalid frame' in \
        report.values['last dropped (tx)']
    later = bus_report(type(status)(**{**status.__dict__, 'dropped_tx_ago': 60.0}), 0, 'v')
    assert later.level == Level.OK and later.values['frames dropped (tx)'] == '1'


# --- 8: the channel written into a recording ----------------------------------------------
def test_a_recording_of_an_slcan_bus_names_its_serial_port(tmp_path):
    record = tmp_path / 'slcan.log'
    with SlcanPeer(symlink=tmp_path / 'ttyACM_rec') as peer:
        io = CanIo(BusConfig(interface='slcan', channel=peer.channel, bitrate=500000,
                             options={'sleep_after_open': 0}, record=str(record)),
                   lambda *frame: None)
        io.start()
        try:
            wait_for(lambda: io.status().connected, what='the slcan bus')
            peer.send(Frame(0x1F4, BMS16_STATUS))
            wait_for(lambda: io.frames_in == 1, what='the frame')
            io.send(Frame(0x305, bytes(8)))
        finally:
            io.stop()
    lines = record.read_text().splitlines()
    assert len(lines) == 2, lines
    assert [line.split()[1] for line in lines] == ['ttyACM_rec', 'ttyACM_rec'], lines
    assert [m.channel for m in can.LogReader(str(record))] == ['ttyACM_rec', 'ttyACM_rec']


# --- 9: a replay that ends the bridge -----------------------------------------------------
def test_replay_exit_ends_the_bridge_after_the_last_messages(tmp_path):
    log = tmp_path / 'drive.log'
    writer = can.Logger(str(log))
    for i in range(9):  # 0.5 s apart, the SoC counting up to 90 % in the last frame
        data = bytearray(BMS16_STATUS)
        data[1] = 82 + i
        writer.on_message_received(can.Message(timestamp=1_790_000_000 + 0.5 * i,
                                               arbitration_id=0x1F4, data=bytes(data),
                                               is_extended_id=False))
    writer.stop()
    ns = f'first_hour_replay_{os.getpid()}'
    with ros_context() as context:
        listener = rclpy.create_node('replay_listener', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(listener)
        socs: list[float] = []
        finished: list[str] = []
        listener.create_subscription(BatteryState, f'/{ns}/bms16/battery_state',
                                     lambda m: socs.append(m.percentage), 50)
        listener.create_subscription(DiagnosticArray, '/diagnostics', lambda m: finished.extend(
            s.message for s in m.status if s.name == f'{ns}/ams_can_bridge: CAN bus'
            and s.message.startswith('replay finished')), 50)
        bridge = Bridge('-r', f'__ns:=/{ns}', '--params-file', params(
            tmp_path, '    devices: [bms16]\n'
            f'    can: {{interface: replay, channel: {log}, replay_exit: true}}\n'))
        try:
            deadline = time.monotonic() + 30
            while bridge.proc.poll() is None and time.monotonic() < deadline:
                executor.spin_once(timeout_sec=0.05)
            for _ in range(20):  # what was delivered before the exit, handed to us now
                executor.spin_once(timeout_sec=0.01)
        finally:
            code = bridge.stop()
            executor.shutdown()
            listener.destroy_node()
    assert code == 0, bridge.output
    assert 'the replay has finished (can.replay_exit): shutting down' in bridge.output
    assert socs and abs(socs[-1] - 0.90) < 1e-6, socs
    assert finished, 'no final diagnostics saying the replay finished'


def test_replay_exit_needs_a_replay():
    settings = bus_settings({**BUS, 'interface': 'virtual', 'channel': 'x',
                             'replay_exit': True})
    assert settings.errors == [
        "can.replay_exit is true but can.interface is 'virtual': only a replayed log ends "
        "(set can.interface to 'replay', or replay_exit to false)"]
