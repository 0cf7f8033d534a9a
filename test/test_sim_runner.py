# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""SimRunner on python-can's virtual bus, and the ``simulator`` executable as a process."""
import contextlib
import fcntl
import os
from pathlib import Path
import pty
import re
import signal
import struct
import subprocess
import sys
import termios
import time
import uuid

import can
import pytest

from ams_can_bridge import registry
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge.sim.main import apply_faults, build_devices
from ams_can_bridge.sim.runner import open_bus, SimRunner

sys.path.insert(0, str(Path(__file__).parent))
from executables import package_executable  # noqa: E402, I100
from helpers import wait_for  # noqa: E402, I100
from slcan_peer import SlcanPeer  # noqa: E402, I100


def simulator() -> str:
    return package_executable('simulator')


class Counter(SimDevice):
    """A tiny simulated device: a counter frame every 10 ms, remembers what it hears."""

    TYPE = 'counter'
    EXTRA_FAULTS = ('stuck_relay',)  # its model-specific fault (apply_faults checks kinds)

    def __init__(self, name=None, arbitration_id=0x100, fail=False):
        super().__init__(name)
        self.arbitration_id = arbitration_id
        self.period = Periodic(0.01)
        self.count = 0
        self.heard = []
        self.fail = fail

    def tick(self, now):
        if self.fail:
            raise RuntimeError('model bug')
        if self.faults.silent or not self.period.due(now):
            return []
        self.count = (self.count + 1) % 256
        return [Frame(self.arbitration_id, bytes([self.count]), False)]

    def on_frame(self, frame, now):
        self.heard.append(frame)


@pytest.fixture
def channel():
    return f'test_sim_{uuid.uuid4().hex[:8]}'


def test_runner_sends_ticks_and_delivers_received_frames(channel):
    sim_bus = open_bus('virtual', channel)
    listener = can.Bus(interface='virtual', channel=channel)
    device = Counter()
    runner = SimRunner(sim_bus, [device])
    runner.start()
    try:
        seen = []
        deadline = time.monotonic() + 5
        while len(seen) < 10 and time.monotonic() < deadline:
            msg = listener.recv(0.5)
            if msg is not None:
                seen.append(msg)
        assert len(seen) == 10
        assert {m.arbitration_id for m in seen} == {0x100}
        counts = [m.data[0] for m in seen]
        assert counts == list(range(counts[0], counts[0] + 10))  # in order, none lost
        assert all(not m.is_extended_id for m in seen)
        listener.send(can.Message(arbitration_id=0x005, data=b'\x21\x00', is_extended_id=False))
        wait_for(lambda: device.heard, what='device heard the frame')
        assert device.heard == [Frame(0x005, b'\x21\x00', False)]
        assert runner.frames_received == 1
        assert runner.frames_sent >= 10
        assert runner.ids_by_device == {'counter': {(0x100, False)}}
    finally:
        runner.stop()
        sim_bus.shutdown()
        listener.shutdown()
    assert not runner.running


def test_runner_survives_device_and_send_errors(channel, caplog):
    sim_bus = open_bus('virtual', channel)
    good, bad = Counter('good'), Counter('bad', 0x200, fail=True)
    runner = SimRunner(sim_bus, [bad, good])
    runner.start()
    try:
        wait_for(lambda: runner.frames_sent >= 5, what='good device keeps sending')
        assert runner.device_errors > 0
        assert 'bad.tick failed' in runner.last_error
        sim_bus.shutdown()   # the adapter goes away under the runner
        wait_for(lambda: runner.send_errors > 0, what='send errors counted')
        assert runner.running
    finally:
        runner.stop()
    assert not runner.running


def test_shared_ids_are_reported(channel):
    bus = open_bus('virtual', channel)
    try:
        runner = SimRunner(bus, [Counter('a'), Counter('b')])
        runner.step(0.0)
        assert runner.shared_ids() == [(0x100, False)]
    finally:
        bus.shutdown()


def test_tick_period_must_be_positive(channel):
    bus = open_bus('virtual', channel)
    try:
        with pytest.raises(ValueError, match='tick_period'):
            SimRunner(bus, [], tick_period=0)
    finally:
        bus.shutdown()


def test_faults_are_applied_by_device_name():
    devices = [Counter('bms16'), Counter('evms3')]
    apply_faults(devices, [('bms16', 'silent', True), ('evms3', 'error', 12),
                           ('evms3', 'drift', 0.3), ('evms3', 'stuck_relay', True)])
    assert devices[0].faults.silent
    assert devices[1].faults.error_code == 12
    assert devices[1].faults.cell_drift_v == 0.3
    assert devices[1].faults.extra == {'stuck_relay': True}
    with pytest.raises(ValueError, match="'sma'"):
        apply_faults(devices, [('sma', 'silent', True)])
    with pytest.raises(ValueError, match='no such fault of evms3; use one of .*silent.*'
                                         'stuck_relay'):
        apply_faults(devices, [('evms3', 'stuck_rely', True)])


def test_registry_paths_all_import():
    """Every simulator and device module the registry names ships (none skipped)."""
    for table in (registry.SIMULATORS, registry.DEVICES):
        for kind, path in table.items():
            assert isinstance(registry.load(path), type), (kind, path)


def test_build_devices_gives_each_type_its_options():
    types = list(registry.SIMULATORS)
    devices = build_devices(types, ams_banks=2, bms12_modules=3, ivt_byte_order='little',
                            ams_pad=True)
    by_name = {d.name: d for d in devices}
    assert sorted(by_name) == sorted(types)
    assert by_name['ams'].bank_count == 2 and by_name['ams'].pad is True
    assert by_name['evms3'].bms12_modules == 3
    assert by_name['ivt_s'].codec.byte_order == 'little'
    assert by_name['bms16'].send_sma is False  # the sma simulator owns 0x351..
    assert build_devices(['bms16'])[0].send_sma is True
    for device in devices:
        frames = device.tick(0.0)
        assert frames and all(isinstance(f, Frame) for f in frames), device.name


def run_simulator(*args, timeout=30):
    return subprocess.run([simulator(), *args], capture_output=True, text=True,
                          timeout=timeout, env=dict(os.environ))


def test_simulator_on_virtual_runs_for_duration_and_exits_0():
    result = run_simulator('--duration', '1', '--interface', 'virtual')
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr
    assert '5 device(s) on virtual:ams_can_bridge' in result.stderr   # startup summary
    for name, first_id in (('ams', '0x300'), ('ivt_s', '0x521'), ('evms3', '0x0000001E'),
                           ('bms16', '0x1F4'), ('sma', '0x351')):
        assert f'{name}[{first_id}' in result.stderr
    assert 'same ID' not in result.stderr                   # defaults do not clash
    assert 'stopped:' in result.stderr


def test_simulator_bus_that_cannot_open_exits_2_with_a_clear_message(tmp_path):
    result = run_simulator('--interface', 'slcan', '--channel', str(tmp_path / 'nothing'),
                           '--option', 'sleep_after_open=0', '--duration', '1',
                           '--devices', ','.join(registry.SIMULATORS))
    assert result.returncode == 2
    assert 'cannot open CAN bus slcan:' in result.stderr
    assert 'Traceback' not in result.stderr


def test_simulator_bad_arguments_exit_2():
    assert run_simulator('--devices', 'toaster').returncode == 2
    result = run_simulator('--fault', 'nobody:silent', '--duration', '0.1',
                           '--devices', list(registry.SIMULATORS)[0])
    assert result.returncode == 2
    assert "'nobody'" in result.stderr
    result = run_simulator('--devices', 'ams', '--ams-banks', '9', '--duration', '0.1')
    assert result.returncode == 2
    assert 'bank_count' in result.stderr and 'Traceback' not in result.stderr


def test_simulator_across_processes_on_slcan_and_sigterm(tmp_path):
    """The simulator's frames reach another process through a (fake) USB-CAN adapter."""
    types = ['ams', 'ivt_s', 'bms16']
    peer = SlcanPeer(symlink=tmp_path / 'ttyCAN0')
    proc = subprocess.Popen(
        [simulator(), '--interface', 'slcan', '--channel', peer.channel, '--bitrate', '500000',
         '--option', 'sleep_after_open=0', '--devices', ','.join(types)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        peer.wait_open(timeout=20)
        # AMS status (car, base 0x300), BMS16 status (4 Hz), IVT-S current; 5 AMS banks
        # send their cells first, so the first 40 frames may all be the AMS's
        peer.wait_received(40, timeout=20)
        wait_for(lambda: {0x300, 500, 0x521} <= {f.arbitration_id for f in peer.received()},
                 timeout=20, what='AMS, BMS16 and IVT-S frames')
        assert peer.bitrate_command == 'S6'
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
        peer.close()
    assert proc.returncode == 0, err
    assert 'Traceback' not in err


def test_simulator_ctrl_c_exits_0_without_traceback():
    proc = subprocess.Popen([simulator(), '--devices', list(registry.SIMULATORS)[0]],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()          # the startup summary: it is running
        assert 'device(s) on virtual:ams_can_bridge' in line
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert 'Traceback' not in err
    assert 'stopped:' in err


def test_simulator_defaults_match_the_example_configs():
    """The simulator with no options speaks to a bridge run on config/*.yaml as they are."""
    import yaml

    from ams_can_bridge.sim.main import build_devices, build_parser, selected_types
    config = Path(__file__).resolve().parents[1] / 'config'

    def params(name):
        return yaml.safe_load((config / name).read_text())['/**']['ros__parameters']
    args = build_parser().parse_args([])
    devices = {d.name: d for d in build_devices(selected_types(args), args.ams_banks,
                                                args.bms12_modules)}
    assert devices['ams'].bank_count == params('ams_ivt.yaml')['ams']['bank_count'] == 5
    assert args.bms12_modules == params('evms3.yaml')['evms3']['bms12_modules']


def test_simulator_start_line_lists_every_id_of_a_dbc_device():
    """Issue 31: the start line listed only a dbc device's primary ID (0x222)."""
    from dbc_fixtures import OUR_BMS_DBC_FILE, OUR_MAPPING_FILE
    result = run_simulator('--dbc', str(OUR_BMS_DBC_FILE), '--mapping', str(OUR_MAPPING_FILE),
                           '--duration', '1', '--channel', f'test_sim_{uuid.uuid4().hex[:8]}')
    assert result.returncode == 0, result.stderr
    # every message the mapping reads, from the BO_ lines of our_bms.dbc: 544 BMS_State,
    # 546 BMS_PackValues, 561 BMS_MinMax, 565 BMS_StateEstimation, 576 BMS_CellVoltages,
    # 592 BMS_CellTemperatures
    assert '1 device(s) on virtual:' in result.stderr
    assert 'dbc[0x220,0x222,0x231,0x235,0x240,0x250]' in result.stderr, result.stderr


def test_simulator_help_lists_every_model_specific_fault():
    """Issue 31: --help named no model-specific fault; each listed one is accepted."""
    result = run_simulator('--help')
    assert result.returncode == 0, result.stderr
    listed = re.findall(r'^    (\w+):(\w+)(=\w+)?  ', result.stdout, re.M)
    # the faults of the simulators' docstrings (sim/ams.py, ivt_s.py, evms3.py, sma.py)
    assert {f'{d}:{k}' for d, k, _ in listed} == {
        'ams:stuck_counter', 'ams:imd_error', 'ivt_s:ocs', 'ivt_s:result_error',
        'ivt_s:measurement_error', 'ivt_s:stuck_counter', 'ivt_s:mute_commands',
        'evms3:config_answer', 'evms3:charger_status', 'sma:alarm', 'sma:warning'}
    for word in ('silent', 'malformed', 'error=CODE', 'drift=VOLTS', 'drift_cell=INDEX',
                 'high_voltage', 'cell_imbalance'):
        assert word in result.stdout, word
    devices = build_devices(list(registry.SIMULATORS))
    samples = {'=ID': 52, '=BITS': 1, '=CONDITION': 'high_voltage'}
    apply_faults(devices, [(d, k, samples[v] if v else True) for d, k, v in listed])
    by_name = {d.name: d for d in devices}
    assert by_name['sma'].faults.extra == {'alarm': 'high_voltage', 'warning': 'high_voltage'}
    assert by_name['ivt_s'].faults.extra['mute_commands'] is True


@contextlib.contextmanager
def ended_at_exit(proc, *fds):
    """Kill proc if it still runs at the end of the block; close the pty fds."""
    try:
        yield
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
        for fd in fds:
            os.close(fd)


def _queued(fd):
    """Bytes waiting in a pty master that nobody reads."""
    return struct.unpack('i', fcntl.ioctl(fd, termios.FIONREAD, b'\0\0\0\0'))[0]


@pytest.mark.parametrize('how', ['SIGINT', 'SIGTERM', '--duration'])
def test_simulator_stops_when_the_other_end_of_its_pty_stops_reading(how):
    """
    Issue 31: blocked in a serial write, the simulator ignored Ctrl-C, SIGTERM, --duration.

    A real pty whose master nobody reads (a bridge that stopped reading): once its buffer
    is full every write waits; each is bounded (SEND_TIMEOUT), so it counts send errors and
    stops within a second.
    """
    master, slave = pty.openpty()
    path = os.ttyname(slave)
    duration = ['--duration', '4'] if how == '--duration' else []
    proc = subprocess.Popen(
        [simulator(), '--interface', 'slcan', '--channel', path, '--option',
         'sleep_after_open=0', '--devices', 'ams,ivt_s', '--status-period', '0.2', *duration],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    filler = os.open(path, os.O_WRONLY | os.O_NOCTTY | os.O_NONBLOCK)  # the other writer
    with ended_at_exit(proc, master, slave, filler):
        assert 'device(s) on slcan:' in proc.stderr.readline()  # the bus is open
        started = time.monotonic()
        # The bridge side stops reading: fill what the pty buffers, so each write waits.
        with pytest.raises(BlockingIOError):
            for _ in range(10000):
                os.write(filler, b'x' * 512)
        assert _queued(master) > 0
        deadline = time.monotonic() + 20
        while True:  # the runner's writes now time out: counted, not blocking for ever
            line = proc.stderr.readline()
            if re.search(r' [1-9]\d* send errors', line):
                break
            assert line and time.monotonic() < deadline, 'no send error counted'
        if how == '--duration':
            proc.wait(timeout=max(1.0, 4 + 1.0 - (time.monotonic() - started)))
        else:
            asked = time.monotonic()
            proc.send_signal(getattr(signal, how))
            proc.wait(timeout=10)
            assert time.monotonic() - asked < 1.0
    err = proc.stderr.read()
    assert proc.returncode == 0, err
    assert 'Traceback' not in err and 'stopped:' in err


def test_ctrl_c_while_the_simulator_opens_an_slcan_port_ends_it_without_traceback():
    """python-can waits 2 s after opening a serial port: Ctrl-C then ends it at once."""
    master, slave = pty.openpty()
    path = os.ttyname(slave)
    proc = subprocess.Popen([simulator(), '--interface', 'slcan', '--channel', path,
                             '--devices', 'ams'], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    with ended_at_exit(proc, master, slave):
        fds = Path(f'/proc/{proc.pid}/fd')

        def port_open():
            try:
                return any(os.path.realpath(fd) == path for fd in fds.iterdir())
            except FileNotFoundError:  # an fd closed while listing: look again
                return False
        wait_for(port_open, timeout=20, what='the simulator to open the port')
        asked = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
        assert time.monotonic() - asked < 1.0
    err = proc.stderr.read()
    assert proc.returncode == 0 and 'Traceback' not in err, err
    assert 'stopped before the bus was open' in err
