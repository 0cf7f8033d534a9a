# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A device type from another package: examples/ams_can_bridge_example_device, installed.

The example (doc/new_device.md) is installed with pip into a folder of this test's own
(``--target``, no dependencies, no build isolation: nothing is fetched and the suite's .venv
is not touched), which the executables find on their PYTHONPATH. Then the installed
``simulator`` sends its frames to a (fake) USB-CAN adapter and obeys a reset-SoC frame,
``probe`` recognises the recording and writes a params file, ``log2bag`` turns the recording
into BatteryState messages with that file, and a live ``bridge`` on an adapter publishes the
BatteryState and sends the reset-SoC command of the example's one command row.
"""
from __future__ import annotations

import os
from pathlib import Path
import shutil
import subprocess
import sys
import time

import can
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import BatteryState
from std_srvs.srv import Trigger

from ams_can_bridge.protocols.common import Frame
from executables import package_executable
from helpers import ros_context, wait_for
from shared import rosbags_read
from slcan_peer import SlcanPeer

EXAMPLE = Path(__file__).resolve().parents[1] / 'examples' / 'ams_can_bridge_example_device'
STATUS_ID, RESET_ID = 0x6B0, 0x6B1
RESET = Frame(RESET_ID, b'\xa5')


@pytest.fixture(scope='module')
def example_env(tmp_path_factory):
    """Install the example into a folder of its own; return the environment that sees it."""
    root = tmp_path_factory.mktemp('example_device')
    source = root / 'src'
    shutil.copytree(EXAMPLE, source)  # pip writes build/ and egg-info beside the sources
    subprocess.run([sys.executable, '-m', 'pip', 'install', '--quiet', '--no-deps',
                    '--no-build-isolation', '--no-index', '--target', str(root / 'site'),
                    str(source)], check=True, timeout=300, capture_output=True)
    assert (root / 'site' / 'ams_can_bridge_example_device' / 'device.py').is_file()
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(root / 'site'),
                                                      env.get('PYTHONPATH')]))
    return env


def run(name, *args, env, timeout=120.0):
    result = subprocess.run([package_executable(name), *args], capture_output=True, text=True,
                            env=env, timeout=timeout)
    assert result.returncode == 0, result.stdout + result.stderr
    assert 'Traceback' not in result.stderr, result.stderr
    return result


def record_simulator(peer: SlcanPeer, env: dict, path: Path) -> list[can.Message]:
    """Run the simulator on the adapter for a few seconds; reset its SoC half-way."""
    proc = subprocess.Popen(
        [package_executable('simulator'), '--interface', 'slcan', '--channel', peer.channel,
         '--bitrate', '500000', '--option', 'sleep_after_open=0', '--devices', 'example_bms',
         '--duration', '20'], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=env)
    messages: list[can.Message] = []
    try:
        peer.wait_open(timeout=30)
        start = time.time()
        while len(messages) < 30 and time.time() - start < 60:
            for frame in peer.received(clear=True):  # stamped as they arrive: 200 ms apart
                messages.append(can.Message(timestamp=time.time(), data=frame.data,
                                            arbitration_id=frame.arbitration_id,
                                            is_extended_id=frame.is_extended_id))
            if len(messages) == 15 and not any(m.arbitration_id == RESET_ID for m in messages):
                peer.send(RESET)  # the simulator takes the command as a BMS would
                messages.append(can.Message(timestamp=time.time(), arbitration_id=RESET_ID,
                                            data=RESET.data, is_extended_id=False))
            time.sleep(0.02)
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=20)
    assert 'Traceback' not in err, err
    writer = can.Logger(str(path))
    for message in messages:
        writer.on_message_received(message)
    writer.stop()
    return messages


def socs(messages: list[can.Message]) -> list[int]:
    return [m.data[4] for m in messages if m.arbitration_id == STATUS_ID]


def test_simulator_probe_and_log2bag_know_the_installed_device_type(example_env, tmp_path):
    # the executables list it as any built-in type
    assert 'example_bms' in run('simulator', '--help', env=example_env).stdout
    bridge_help = run('ams-can-bridge', '--help', env=example_env).stdout
    assert 'pack, example_bms (default' in bridge_help
    log = tmp_path / 'example.log'
    with SlcanPeer(symlink=tmp_path / 'ttyCAN0') as peer:
        messages = record_simulator(peer, example_env, log)
    assert {m.arbitration_id for m in messages} == {STATUS_ID, RESET_ID}
    levels = socs(messages)
    assert len(levels) >= 25 and levels[0] == 80 and levels[-1] == 99, levels  # the reset
    # probe: recognised by the example's recogniser, written as an instance of its type
    params = tmp_path / 'params.yaml'
    report = run('probe', str(log), '--output', str(params), env=example_env).stdout
    assert 'example_bms: example BMS at 0x6B0, confidence medium' in report, report
    text = params.read_text()
    assert 'devices: [example_bms]' in text and 'type: example_bms' in text, text
    assert 'base_id: 1712' in text, text
    # log2bag with probe's file: one BatteryState per status frame, decoded by the example
    run('log2bag', str(log), str(tmp_path / 'bag'), '--params-file', str(params),
        env=example_env)
    states = [m for _, m in rosbags_read(str(tmp_path / 'bag'))['/example_bms/battery_state']]
    assert [round(m.percentage * 100) for m in states] == levels
    assert all(m.present and m.current == pytest.approx(-12.0) for m in states)
    assert states[0].voltage == pytest.approx(52.0)


def test_the_bridge_publishes_the_device_and_sends_its_command(example_env, tmp_path):
    ns = f'example_device_{os.getpid()}'
    params = tmp_path / 'bridge.yaml'
    with SlcanPeer(symlink=tmp_path / 'ttyCAN1') as peer:
        params.write_text(f'''/**:
  ros__parameters:
    can: {{interface: slcan, channel: {peer.channel}, bitrate: 500000,
           options: [sleep_after_open=0]}}
    devices: [pack1]
    pack1: {{type: example_bms, capacity_ah: 50.0}}
    commands_allowed: true
    commands_enabled: true
''')
        proc = subprocess.Popen([package_executable('bridge'), '--ros-args', '-r',
                                 f'__ns:=/{ns}', '--params-file', str(params)],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                env=example_env)
        try:
            with ros_context() as context:
                node = rclpy.create_node('example_listener', context=context)
                executor = SingleThreadedExecutor(context=context)
                executor.add_node(node)
                got: list[BatteryState] = []
                node.create_subscription(BatteryState, f'/{ns}/pack1/battery_state',
                                         got.append, 50)
                client = node.create_client(Trigger, f'/{ns}/pack1/reset_soc')
                peer.wait_open(timeout=30)

                def heard():
                    peer.send(Frame(STATUS_ID, bytes.fromhex('501488FF50410001')))
                    executor.spin_once(timeout_sec=0.1)
                    return [m for m in got if m.present]
                wait_for(heard, 60, 'a present BatteryState of the example device')
                state = heard()[-1]
                assert state.percentage == pytest.approx(0.80) and state.capacity == 50.0
                assert state.voltage == pytest.approx(52.0)
                assert state.current == pytest.approx(-12.0)
                assert client.wait_for_service(timeout_sec=30)
                peer.received(clear=True)
                future = client.call_async(Trigger.Request())
                executor.spin_until_future_complete(future, timeout_sec=30)
                answer = future.result()
                assert answer is not None and answer.success, answer
                assert 'reset the SoC' in answer.message, answer.message
                wait_for(lambda: RESET in peer.received(), 10, 'the reset-SoC frame')
                executor.shutdown()
                node.destroy_node()
        finally:
            if proc.poll() is None:
                proc.terminate()
            out, _ = proc.communicate(timeout=30)
    assert 'Traceback' not in out, out
    assert 'pack1' in out and 'example_bms' in out, out
