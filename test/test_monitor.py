# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``monitor`` executable on a real bridge, and the table it shares with the demo.

The end-to-end test runs a bridge in namespace car1 on a virtual bus (simulated AMS and
IVT-S, a dbc device fed the hand-written frames of test/fixtures/our_bms.dbc) and the
installed ``monitor --namespace car1 --plain`` as a process: its table shows each device's
values, the dbc device STALE once its frames stop, every device STALE once the bridge is
gone, and the bridge never sees a service call from it.
"""
import os
import re
import signal
import subprocess
import sys
import threading
import time

import can
import pytest

from ams_can_bridge.ros import monitor
from ams_can_bridge.ros.bridge_node import NODE_NAME
from ams_can_bridge.sim.runner import SimRunner
from dbc_fixtures import FRAMES, OUR_PARAMS
from executables import package_executable
from helpers import wait_for


NAMESPACE = 'car1'


def monitor_executable() -> str:
    return package_executable('monitor')


class Output:
    """A process's stdout, read on a thread, cut into the --plain snapshots."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc
        self.text = ''
        self.lock = threading.Lock()
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            with self.lock:
                self.text += line

    def snapshots(self) -> list[str]:
        """Return the complete snapshots so far (the last one only once the next began)."""
        with self.lock:
            parts = self.text.split('--- t = ')[1:]
        return parts[:-1] if self.proc.poll() is None else parts

    def rows(self) -> dict[str, list[str]]:
        """Return the device rows of the newest complete snapshot (name -> its words)."""
        shots = self.snapshots()
        return rows_of(shots[-1]) if shots else {}


def rows_of(snapshot: str) -> dict[str, list[str]]:
    lines = snapshot.splitlines()
    start = next((i for i, line in enumerate(lines) if line.startswith('DEVICE')), None)
    if start is None:
        return {}
    rows = {}
    for line in lines[start + 1:]:
        if not line.strip():
            break
        rows[line.split()[0]] = line.split()
    return rows


def cells_of(words: list[str]) -> list[str]:
    """
    Return a row's five value cells (voltage, current, SOC, cells, temperature), as text.

    Read from the right, before the level: a value is a number and its unit, an unknown one
    the single word 'n/a' (the state before them may be words of its own).
    """
    cells: list[str] = []
    end = len(words) - 1  # the last word is the level
    while len(cells) < 5 and end > 1:
        width = 1 if words[end - 1] == 'n/a' else 2
        cells.insert(0, ' '.join(words[end - width:end]))
        end -= width
    return cells


def table_words(value: float, unit: str) -> list[str]:
    """Return the words of one table cell, formatted as the table does (one decimal)."""
    return [f'{round(value, 1) + 0.0:.1f}', unit]


def start_monitor(*args: str) -> tuple[subprocess.Popen, Output]:
    proc = subprocess.Popen([monitor_executable(), '--plain', *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=dict(os.environ))
    return proc, Output(proc)


def ended(proc: subprocess.Popen, sig: int | None = None) -> tuple[int, str]:
    """Send sig (None: wait for --duration); return the exit code and stderr, bounded."""
    if sig is not None and proc.poll() is None:
        proc.send_signal(sig)
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=10)
        raise AssertionError(f'the monitor did not end within 30 s ({sig or "--duration"})')
    return proc.returncode, proc.stderr.read()


def test_monitor_help_answers_without_starting_ros():
    code = ('import sys\n'
            'from ams_can_bridge.ros.monitor import main\n'
            'try:\n    main(["--help"])\nexcept SystemExit as exc:\n    code = exc.code\n'
            'print("EXIT", code, "rclpy" in sys.modules)\n')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=60)
    assert result.stdout.strip().endswith('EXIT 0 False'), result.stdout + result.stderr
    assert '--namespace' in result.stdout and '--duration' in result.stdout
    installed = subprocess.run([monitor_executable(), '--help'], capture_output=True, text=True,
                               timeout=60)
    assert installed.returncode == 0 and installed.stdout.startswith('usage: monitor')


@pytest.mark.parametrize('args, named', [
    (['--namespace', 'car 1'], '--namespace'), (['--node', 'my-bridge'], '--node'),
    (['--duration', '-1'], '--duration'), (['--stale-after', '0'], '--stale-after')])
def test_monitor_refuses_a_bad_argument_with_one_line(args, named):
    result = subprocess.run([monitor_executable(), *args], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 2
    assert 'Traceback' not in result.stderr
    assert named in result.stderr.splitlines()[-1], result.stderr


def test_the_monitor_knows_the_bridges_node_name():
    assert monitor.BRIDGE_NODE == NODE_NAME


def test_monitor_without_a_bridge_says_what_it_waits_for_and_ends_after_duration():
    started = time.monotonic()
    proc, out = start_monitor('--namespace', 'nobody_here', '--duration', '1.5')
    code, err = ended(proc)
    assert code == 0 and 'Traceback' not in err, err
    assert time.monotonic() - started < 30
    shots = out.snapshots()
    assert shots and 'waiting for /diagnostics from nobody_here/ams_can_bridge' in shots[-1]
    assert rows_of(shots[-1]) == {}


@pytest.mark.slow
def test_monitor_shows_a_namespaced_bridge_marks_stale_devices_and_calls_nothing(rig_factory):
    from ams_can_bridge.registry import load, SIMULATORS
    rig = rig_factory({
        'devices': ['ams', 'ivt_s', 'pack'], 'ams.bank_count': 1,
        'pack.type': 'dbc', **{f'pack.{k}': v for k, v in OUR_PARAMS.items()},
        'pack.stale_timeout': 1.0, 'commands_allowed': True}, namespace=NAMESPACE)
    calls = []
    calling = rig.node.gate.calling

    def counted(source):  # every command service call of the bridge passes here
        calls.append(source)
        return calling(source)
    rig.node.gate.calling = counted
    ams = load(SIMULATORS['ams'])(name='ams', bank_count=1)
    ivt = load(SIMULATORS['ivt_s'])(name='ivt_s', current_fn=ams.pack_current_a,
                                    voltage_fn=ams.pack_voltage_v)
    sim_bus = can.Bus(interface='virtual', channel=rig.channel)
    runner = SimRunner(sim_bus, [ams, ivt])
    runner.start()
    feeding = threading.Event()
    feeding.set()
    finished = threading.Event()

    def feed():  # the dbc device's BMS: the hand-written frames, 10 times a second
        while not finished.is_set():
            if feeding.is_set():
                for can_id, data in FRAMES.values():
                    rig.send(can_id, data)
            finished.wait(0.1)
    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    proc, out = start_monitor('--namespace', NAMESPACE, '--interval', '0.25',
                              '--stale-after', '1.5', '--duration', '120')
    lost, lost_out = start_monitor()  # no namespace: not this bridge
    try:
        def live():
            # numbers come with the bridge's battery_state, the level with its /diagnostics,
            # each in its own time (the first battery_state may come before the pack's other
            # frames): wait for a snapshot with every number and every level, none STALE (a
            # machine that stalls the feeding threads for a stale_timeout makes a device
            # stale for a moment, rightly)
            rows = out.rows()
            return rows if set(rows) == {'ams', 'ivt_s', 'pack'} and all(
                words[-1] in ('OK', 'WARN', 'ERROR') and 'n/a' not in cells_of(words)[:2]
                for words in rows.values()) and 'n/a' not in cells_of(rows['pack']) else None
        rows = wait_for(live, 60, 'the monitor to show the three devices with values')
        # the dbc device: the values of the hand-written frames (our_bms.dbc), exactly; the
        # BMS flags cell 003 invalid, so the device WARNs and says so where a state would be
        # (the state cell holds the head of its message: words of their own)
        assert rows['pack'][-11:] == ['400.0', 'V', '-50.0', 'A', '87.5', '%',
                                      '3.690..3.710', 'V', '35.0', 'C', 'WARN']
        assert ' '.join(rows['pack'][1:-11]) == '1 of 4 cell vol.'
        # AMS and IVT-S idle: constant values, as the bridge holds them (a snapshot and the
        # bridge's report of one moment: a stall of the simulator may blank a report between
        # two snapshots; an unknown value is 'n/a' in the table, never 'nan')
        for name in ('ams', 'ivt_s'):
            def shown(name=name):
                report = rig.node.devices[name].battery_report()
                wanted = table_words(report.voltage, 'V') + table_words(report.current, 'A')
                return out.rows().get(name, [])[2:6] == wanted
            wait_for(shown, 30, f"the {name} row to show the bridge's voltage and current")
        assert rows['ams'][1] == 'IDLE' and rows['ivt_s'][1] == 'measuring'
        assert f'monitor {NAMESPACE}/{NODE_NAME}' in out.snapshots()[-1]
        assert 'CAN bus: OK (connected)' in out.snapshots()[-1]
        # it only subscribes: no client in the graph, the bridge's services saw no call
        name = f'ams_can_bridge_monitor_{proc.pid}'
        wait_for(lambda: name in rig.node.get_node_names(), 10, 'the monitor in the graph')
        assert rig.node.get_client_names_and_types_by_node(name, '/') == []
        subscribed = {t for t, _ in rig.node.get_subscriber_names_and_types_by_node(name, '/')}
        assert f'/{NAMESPACE}/pack/battery_state' in subscribed

        # the wrong namespace: nothing shown, and it says which bridge it did see
        seen = wait_for(lambda: next((shot for shot in reversed(lost_out.snapshots())
                                      if f'bridges seen: {NAMESPACE}/{NODE_NAME}' in shot),
                                     None), 60, 'the other monitor to name the bridge it saw')
        assert 'waiting for /diagnostics from ams_can_bridge' in seen
        assert rows_of(seen) == {}
        code, err = ended(lost, signal.SIGINT)
        assert code == 0 and 'Traceback' not in err, err

        feeding.clear()  # the dbc BMS falls silent: the bridge marks it STALE, the AMS OK
        stale = wait_for(lambda: (lambda r: r if r.get('pack', [''])[-1] == 'STALE'
                                  and 'n/a' in r['pack'] and r['ams'][-1] == 'OK' else None)(
                                      out.rows()), 30, 'the dbc device marked STALE')
        assert stale['pack'] == ['pack', 'silent'] + ['n/a'] * 5 + ['STALE']

        rig.close()  # the bridge is gone: the monitor marks everything STALE itself
        gone = wait_for(lambda: (lambda r: r if r and all(
            w[-1] == 'STALE' and w[1:3] == ['no', 'data'] for w in r.values()) else None)(
                out.rows()), 30, 'every device marked STALE by the monitor')
        assert set(gone) == {'ams', 'ivt_s', 'pack'}
        last = out.snapshots()[-1]
        assert 'CAN bus: STALE (no /diagnostics from the bridge for' in last
        assert re.search(r'  pack: nothing from the bridge for \d+ s', last), last
    finally:
        finished.set()
        runner.stop()
        sim_bus.shutdown()
        code, err = ended(proc, signal.SIGINT)
        if lost.poll() is None:
            ended(lost, signal.SIGINT)
    assert code == 0 and 'Traceback' not in err, err
    assert calls == []
