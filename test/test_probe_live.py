# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
probe live over slcan on a pty (the test plays the USB-CAN adapter), then the bridge.

The simulators run in real time in this process and their frames go to the adapter side
of a pty (``SlcanPeer``). The installed ``probe`` listens on the other side, writes its
params file; the installed ``bridge`` is then started with exactly that file on the same
adapter, and a ROS subscriber here checks what it publishes. What must hold:

- probe never transmits: the adapter received no frame from it, and it opened the channel
  listen-only ('L', never 'O'); with ``--bitrate auto`` it went through the rates and found
  the one the simulated bus runs at (the adapter delivers frames only at that rate);
- its params file decides what the simulator was configured with;
- every BatteryState the bridge publishes once every frame group was heard equals the
  state of the real device classes (configured with the simulator's truth) after the same
  frames: same cells, same values, same signs.
"""
from __future__ import annotations

import math
import os
from pathlib import Path
import subprocess
import sys
import threading
import time

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import BatteryState

from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.offline.converter import NODE_NAME
from ams_can_bridge.offline.params_file import FileParams, load_parameters
from ams_can_bridge.protocols.common import Frame
from executables import bridge_executable, probe_executable
from helpers import interrupt, ros_context, values_of
from probe_variants import BY_NAME, PROFILE_VARIANTS, Variant, VARIANTS
from slcan_peer import SlcanPeer

SLCAN_RATE = {500_000: 'S6', 250_000: 'S5'}
LISTEN_S = 3.0
WARM_UP_S = 2.5  # s after the bridge's first message: every group (1 s cycles) heard again


def nan_free(values: tuple) -> tuple:
    """Make a values_of tuple hashable and comparable: NaN as a string."""
    return tuple(nan_free(v) if isinstance(v, tuple) else
                 ('nan' if isinstance(v, float) and math.isnan(v) else v) for v in values)


class Feeder:
    """The simulated bus in real time: frames to the adapter, and to reference devices."""

    def __init__(self, peer: SlcanPeer, variant: Variant) -> None:
        self.peer = peer
        self.sims = variant.build()
        self.rate = SLCAN_RATE[variant.bitrate]
        self.now = time.monotonic()
        truth = FileParams({k: v for k, v in variant.truth.items() if k != 'devices'})
        self.devices = DeviceSet(variant.truth['devices'], truth.declare, clock=lambda: self.now)
        truth.raise_errors()
        self.states: dict[str, set] = {name: set() for name in self.devices.devices}
        self.sent = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='feeder', daemon=True)

    def __enter__(self) -> 'Feeder':
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)

    def _run(self) -> None:
        while not self._stop.wait(0.002):
            self.now = time.monotonic()
            for sim in self.sims:
                for frame in sim.tick(self.now):
                    # the adapter hears the bus only at its rate, and only while open
                    if self.peer.bitrate_command == self.rate and self.peer.send(frame):
                        self.sent += 1
                        self._reference(frame)

    def _reference(self, frame: Frame) -> None:
        for device in self.devices.handle_frame(frame.arbitration_id, frame.data,
                                                frame.is_extended_id, self.now):
            self.states[device.name].add(nan_free(values_of(device.battery_report())))


def run_probe(peer: SlcanPeer, out: Path, bitrate: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [probe_executable(), '--interface', 'slcan', '--channel', peer.channel, '--bitrate',
         bitrate, '--duration', str(LISTEN_S), '--option', 'sleep_after_open=0', '--output',
         str(out)], capture_output=True, text=True, timeout=90, env=dict(os.environ))


def assert_listened_only(peer: SlcanPeer) -> None:
    assert peer.received() == [], 'probe transmitted frames'
    opens = [c for c in peer.commands if c[:1] in 'OL']
    assert opens and all(c == 'L' for c in opens), peer.commands


@pytest.mark.parametrize('name, bitrate', [
    ('ams_3_ivt_little_shifted_results_off', '500000'),
    ('evms3_6_modules', 'auto'),
    ('sma_pylontech', '500000'),
    ('sma_victron_tenth_volt', '500000'),
    ('bms16_inverter', '500000'),
    ('profile_orion_bms2', '500000'),
    ('bms16_standard', 'auto'),
    # every other variant the simulator plays, at its own rate (each also runs as a log:
    # test_probe_roundtrip)
    *[(v.name, str(v.bitrate)) for v in VARIANTS + PROFILE_VARIANTS
      if v.name not in {'ams_3_ivt_little_shifted_results_off', 'evms3_6_modules',
                        'sma_pylontech', 'sma_victron_tenth_volt', 'bms16_inverter',
                        'profile_orion_bms2', 'bms16_standard'}],
])
def test_live_probe_then_bridge_reads_what_the_simulator_sends(tmp_path, name, bitrate):
    variant = BY_NAME[name]
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_probe')
    out = tmp_path / 'probe.yaml'
    with Feeder(peer, variant) as feeder:
        result = run_probe(peer, out, bitrate)
        assert result.returncode == 0, result.stderr
        assert 'Traceback' not in result.stderr + result.stdout
        assert_listened_only(peer)
        if bitrate == 'auto':
            tried = [c for c in peer.commands if c[:1] == 'S']
            assert tried[:2] == ['S6', 'S5'], peer.commands  # 500k first, then 250k
            assert f'{variant.bitrate} bit/s' in result.stderr
            assert (f'at {variant.bitrate} bit/s (listen-only, rate found by trying the '
                    'standard ones)') in result.stdout
            comments = ' '.join(out.read_text().replace('#', ' ').split())
            assert '(listen-only): 500000: 0 frames, 250000: ' in comments  # the bitrate's
        params = load_parameters(str(out), NODE_NAME)
        assert params['can.bitrate'] == variant.bitrate
        assert params['can.interface'] == 'slcan' and params['can.channel'] == peer.channel
        assert params['commands_allowed'] is False
        for key, value in {**variant.truth, **variant.expect}.items():
            assert params.get(key) == value, (key, result.stdout)
        published = bridge_messages(out, variant)
        assert peer.received() == [], 'the bridge (commands off) transmitted frames'
    for device, messages in published.items():
        assert messages, f'{device}: nothing published after the warm-up'
        cells = variant.cells.get(device)
        volts = variant.volts.get(device)
        for msg in messages:
            if cells:
                assert len(msg.cell_voltage) == cells
            if volts:  # the pack's voltage, not 10x off (an SMA 0x356 in 0.1 V)
                assert volts[0] < msg.voltage < volts[1], (device, msg.voltage)
            assert nan_free(values_of(msg)) in feeder.states[device], (
                device, values_of(msg))


def bridge_messages(params: Path, variant: Variant) -> dict[str, list]:
    """Run the bridge on the probe's file; return what it published after the warm-up."""
    with ros_context() as ctx:
        node = rclpy.create_node('probe_live_listener', context=ctx)
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(node)
        try:
            return _spin_bridge(node, executor, params, variant)
        finally:
            executor.shutdown()
            node.destroy_node()


def _spin_bridge(node, executor, params: Path, variant: Variant) -> dict[str, list]:
    ns = f'probe_live_{os.getpid()}'
    got: dict[str, list] = {name: [] for name in variant.truth['devices']}
    for name in got:
        node.create_subscription(BatteryState, f'/{ns}/{name}/battery_state',
                                 lambda m, n=name: got[n].append((time.monotonic(), m)), 100)
    proc = subprocess.Popen([bridge_executable(), '--ros-args', '-r', f'__ns:=/{ns}',
                             '--params-file', str(params)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=dict(os.environ))
    try:
        deadline = time.monotonic() + 60
        first = None
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
            if first is None and all(any(m.present for _, m in v) for v in got.values()):
                first = time.monotonic()
            if first is not None and time.monotonic() > first + WARM_UP_S + 2.0:
                break
        assert first is not None, {n: len(v) for n, v in got.items()}
        assert proc.poll() is None
    finally:
        output = interrupt(proc)
    assert proc.returncode == 0 and 'Traceback' not in output, output
    return {n: [m for t, m in v if t > first + WARM_UP_S and m.present]
            for n, v in got.items()}


def test_probe_never_sends_on_a_virtual_bus(capsys):
    """Run probe on python-can's virtual bus: a third bus hears only what the simulator sent."""
    import can

    from ams_can_bridge.probe.main import main
    channel = f'probe_silent_{os.getpid()}'
    sims = BY_NAME['bms16_standard'].build()
    sender = can.Bus(interface='virtual', channel=channel)
    witness = can.Bus(interface='virtual', channel=channel)
    stop = threading.Event()
    sent: list[Frame] = []

    def play() -> None:
        while not stop.wait(0.002):
            for sim in sims:
                for frame in sim.tick(time.monotonic()):
                    sender.send(can.Message(arbitration_id=frame.arbitration_id,
                                            data=frame.data,
                                            is_extended_id=frame.is_extended_id))
                    sent.append(frame)
    thread = threading.Thread(target=play, daemon=True)
    thread.start()
    try:
        code = main(['--interface', 'virtual', '--channel', channel, '--duration', '1.5'])
    finally:
        stop.set()
        thread.join(timeout=5)
    heard = []
    while (msg := witness.recv(0.1)) is not None:
        heard.append(Frame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id))
    sender.shutdown()
    witness.shutdown()
    assert code == 0
    assert 'BMS16 (standard form)' in capsys.readouterr().out
    assert heard == sent  # nothing of probe's among them


def test_probe_help_and_a_log_load_no_ros_module(tmp_path):
    """Check that probe --help and a whole probe run import nothing of ROS."""
    from ams_can_bridge.sim.recording import write_log
    log = tmp_path / 'bus.log'
    write_log(str(log), BY_NAME['sma'].build(), 3.0)
    code = ('import sys\nfrom ams_can_bridge.probe.main import main\n'
            'try:\n    main(["--help"])\nexcept SystemExit as exc:\n    assert exc.code == 0\n'
            f'assert main([{str(log)!r}, "--output", {str(tmp_path / "p.yaml")!r}]) == 0\n'
            'print("ROS:", sorted(m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "rcl_interfaces", "sensor_msgs", "diagnostic_msgs", "std_msgs")))\n')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
    assert 'usage: probe' in result.stdout
    assert result.stdout.strip().endswith('ROS: []'), result.stdout
