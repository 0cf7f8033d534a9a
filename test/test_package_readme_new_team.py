# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The way from ./dev demo to the car stays true.

The commands of doc/getting_started.md and doc/real_bus.md are run here (the README's ten
steps link to them).

The two-process example runs as written (the bundled serial link, the simulator, the bridge,
with only the /tmp paths moved into the test's directory); the several-cars params file is
loaded by two bridges in their namespaces; the list of parameters that can change at run
time (doc/parameters.md) is the node's own.
"""
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import threading
import time

import pytest
import rclpy
import yaml

from doc_blocks import block_after, commands, section
from helpers import every_device_bridge

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


class Output:
    """Collect a process's stderr lines on a thread (the bridge logs there)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.lines: list[str] = []
        self.thread = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self.thread.start()

    def _read(self, proc: subprocess.Popen) -> None:
        for line in proc.stderr:
            self.lines.append(line)

    def wait_for(self, text: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while not any(text in line for line in self.lines):
            assert time.monotonic() < deadline, f'{text!r} not seen in {self.lines[-20:]}'
            time.sleep(0.05)


def test_simulator_and_bridge_as_two_processes_over_the_bundled_link(tmp_path):
    two = section('getting_started', 'Simulator and bridge as two processes')
    steps = commands(block_after(two, 'as two processes', 'bash'))
    assert steps[0][0] == 'socat'  # shown first; this machine may not have it
    link, sim, bridge = steps[1:]
    assert link[:2] == ['python', 'bench/pty_link.py'] and sim[0] == 'simulator'
    assert bridge[0] == 'bridge'

    def local(argv: list[str]) -> list[str]:
        exe = {'python': sys.executable, 'simulator': str(BIN / 'simulator'),
               'bridge': str(BIN / 'bridge')}[argv[0]]
        return [exe] + [a.replace('/tmp/', f'{tmp_path}/') for a in argv[1:]]
    procs = []
    try:
        procs.append(subprocess.Popen(local(link), cwd=ROOT, stderr=subprocess.PIPE,
                                      text=True))
        for name in ('ttyBRIDGE', 'ttySIM'):
            deadline = time.monotonic() + 10
            while not (tmp_path / name).exists():
                assert time.monotonic() < deadline, f'the link did not make {name}'
                time.sleep(0.05)
        procs.append(subprocess.Popen(local(sim), cwd=ROOT, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.PIPE, text=True))
        procs.append(subprocess.Popen(local(bridge), cwd=ROOT, stderr=subprocess.STDOUT,
                                      stdout=subprocess.PIPE, text=True))
        procs[-1].stderr = procs[-1].stdout
        out = Output(procs[-1])
        for text in (f'CAN bus slcan:{tmp_path}/ttyBRIDGE connected',
                     'ams: first status frame received', 'ivt_s: first status frame received'):
            out.wait_for(text, timeout=30)
        assert not any('bank' in line.lower() and 'mismatch' in line.lower()
                       for line in out.lines)
        # "In another shell ... monitor": the demo's table of this bridge (a bounded run)
        watch, = commands(block_after(two, 'In another shell', 'bash'))
        assert watch == ['monitor']
        shown = subprocess.run([str(BIN / 'monitor'), '--plain', '--duration', '4'],
                               capture_output=True, text=True, timeout=60)
        assert shown.returncode == 0, shown.stderr
        last = shown.stdout.split('--- t = ')[-1]
        for name in ('ams', 'ivt_s'):
            assert re.search(rf'^{name} .* V .* OK$', last, re.M), last
    finally:
        for proc in reversed(procs):
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in reversed(procs):
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)


def test_the_several_cars_params_file_configures_each_bridge(tmp_path):
    from rclpy.parameter import Parameter

    from ams_can_bridge.ros.bridge_node import BridgeNode
    text = block_after(section('real_bus', 'Several buses or cars side by side'),
                       'Run one bridge per bus', 'yaml')
    path = tmp_path / 'cars.yaml'
    path.write_text(text)
    sections = yaml.safe_load(text)
    assert set(sections) == {'/car1/ams_can_bridge', '/car2/ams_can_bridge'}
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', '--params-file', str(path)], context=context)
    try:
        got = {}
        for car in ('car1', 'car2'):
            # the file's buses may not exist here: a virtual bus of its own, the rest as read
            node = BridgeNode(context=context, namespace=car, parameter_overrides=[
                Parameter('can.interface', value='virtual')])
            try:
                got[car] = (list(node.devices), node.bus_config.channel,
                            node.status_prefix())
            finally:
                node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
    assert got == {'car1': (['ams', 'ivt_s'], 'can0', 'car1/ams_can_bridge'),
                   'car2': (['bms16'], 'can1', 'car2/ams_can_bridge')}


def test_the_parameters_that_change_at_run_time_are_the_nodes_writable_ones():
    paragraph = section('parameters', 'What can change at run time').strip().split('\n\n')[0]
    names = paragraph.split('):', 1)[1].split('Every other', 1)[0]  # after the instances
    listed = re.findall(r'`([a-z0-9_.*]+)`', names)
    assert 'commands_enabled' in listed
    with every_device_bridge('readme-new-team') as node:
        writable = {name for name in node._parameters if name != 'use_sim_time'
                    and not node.describe_parameter(name).read_only}
        every = set(node._parameters)

    def matches(pattern: str) -> set[str]:
        if pattern.endswith('.*'):
            return {n for n in every if n.startswith(pattern[:-1])}
        return {pattern} & every
    covered = set().union(*(matches(p) for p in listed))
    for pattern in listed:
        assert matches(pattern), f'doc/parameters.md names {pattern}, which the node lacks'
        assert matches(pattern) <= writable, f'{pattern} is read-only in the node'
    assert covered == writable, f'writable but not in doc/parameters.md: {writable - covered}'


@pytest.mark.parametrize('heading', ['The executables'])
def test_the_executables_are_where_getting_started_says(heading):
    for argv in commands(block_after(section('getting_started', heading), '', 'bash'))[1:]:
        if argv[0] in ('bridge', 'simulator', 'log2bag', 'monitor', 'probe'):
            assert os.access(BIN / argv[0], os.X_OK), argv[0]
    for exe in ('simulator', 'log2bag', 'monitor', 'probe'):
        done = subprocess.run([str(BIN / exe), '--help'], capture_output=True, text=True,
                              timeout=60)
        assert done.returncode == 0 and 'usage:' in done.stdout, done.stderr
