# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Shared parts of the benchmarks: linked serial ports, processes, CPU and memory readings.

Everything here keeps DDS on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) on a
domain of the benchmark's own, and every process it starts is stopped when the block ends.
CPU is read from /proc (utime + stime of the whole process, all threads), so a figure is
what the process cost the machine, whatever it did with its threads.
"""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from typing import Iterator, Sequence

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', str(150 + os.getpid() % 50))
PYTHON = sys.executable
TICKS = os.sysconf('SC_CLK_TCK')
BENCH = Path(__file__).resolve().parent
# Options both sides use on the linked ptys: no 2 s wait for an adapter to boot.
SLCAN_OPEN = ['sleep_after_open=0']


def env() -> dict[str, str]:
    """Return the environment for child processes (network rule, our domain)."""
    e = dict(os.environ)
    e['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    e['PYTHONUNBUFFERED'] = '1'
    return e


def cpu_seconds(pid: int) -> float:
    """Return the CPU time (user + system, all threads) a process has used so far.

    Read from each live thread's /proc/PID/task/TID/schedstat (nanoseconds) where the kernel
    has it: /proc/PID/stat counts in clock ticks (10 ms), which over a 3 s window of a
    process using 8 % of a core is +-4 % from rounding alone. Threads that ended are not
    counted, so use it on processes whose threads live for the whole measurement.
    """
    try:
        total = 0
        for tid in os.listdir(f'/proc/{pid}/task'):
            try:
                total += int(Path(f'/proc/{pid}/task/{tid}/schedstat').read_text().split()[0])
            except FileNotFoundError:  # the thread ended meanwhile
                pass
        return total / 1e9
    except (FileNotFoundError, ValueError, IndexError):
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / TICKS


def rss_mb(pid: int) -> float:
    """Return the resident set size of a process in MB."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024.0
    return float('nan')


def cpu_share(pid: int, seconds: float) -> float:
    """Return the share of one core a process uses over the next `seconds` (1.0 = 100 %)."""
    c0, t0 = cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)
    return (cpu_seconds(pid) - c0) / (time.monotonic() - t0)


@contextlib.contextmanager
def pty_pair() -> Iterator[tuple[str, str]]:
    """Yield two linked serial ports, as an slcan adapter's two sides.

    socat where it is installed (BENCH_PTY_LINK=python forces the other way); else
    bench/pty_link.py, the same link in Python, so a machine with nothing but Python runs
    the suite.
    """
    work = tempfile.mkdtemp(prefix='bench_pty_')
    a, b = os.path.join(work, 'A'), os.path.join(work, 'B')
    if shutil.which('socat') and os.environ.get('BENCH_PTY_LINK') != 'python':
        args = ['socat', f'pty,raw,echo=0,link={a}', f'pty,raw,echo=0,link={b}']
    else:
        args = [PYTHON, str(BENCH / 'pty_link.py'), a, b]
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 5.0
        while not (os.path.exists(a) and os.path.exists(b)):
            if time.monotonic() > deadline:
                raise RuntimeError(f'{args[0]} did not create the linked ptys')
            time.sleep(0.02)
        yield a, b
    finally:
        proc.terminate()
        proc.wait(timeout=5)
        shutil.rmtree(work, ignore_errors=True)


@contextlib.contextmanager
def process(args: Sequence[str], settle: float = 0.0) -> Iterator[subprocess.Popen]:
    """Run a child process for the block (SIGINT, then kill, at the end); its output is kept
    in a temporary file and shown if it dies early."""
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen(list(args), env=env(), stdout=log, stderr=subprocess.STDOUT)
    try:
        if settle:
            time.sleep(settle)
        if proc.poll() is not None:
            log.seek(0)
            tail = log.read().decode(errors='replace')[-2000:]
            raise RuntimeError(f'{args[:3]} exited with {proc.returncode}:\n{tail}')
        yield proc
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        log.close()


def bridge_args(params: str) -> list[str]:
    """Return the command line of the bridge with a parameters file."""
    return [PYTHON, '-m', 'ams_can_bridge.ros.bridge_main', '--ros-args', '--params-file',
            params, '--log-level', 'warn']


def simulator_args(channel: str, banks: int = 5, modules: int = 16,
                   devices: str = 'ams,ivt_s,evms3,bms16,sma') -> list[str]:
    """Return the command line of the simulator on one side of the ptys."""
    return [PYTHON, '-m', 'ams_can_bridge.sim.main', '--interface', 'slcan', '--channel',
            channel, '--devices', devices, '--ams-banks', str(banks), '--bms12-modules',
            str(modules), '--quiet'] + [a for o in SLCAN_OPEN for a in ('--option', o)]


def write_params(path: str, interface: str, channel: str, options: Sequence[str],
                 banks: int = 5, modules: int = 16, commands: bool = False,
                 devices: Sequence[str] = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma'),
                 sections: dict[str, dict] | None = None,
                 extra: dict | None = None) -> str:
    """
    Write the bridge's parameters file for a benchmark run.

    ``sections``: more instances (name: section); ``extra``: node parameters.
    """
    import yaml
    params = {
        'can': {'interface': interface, 'channel': channel, 'options': list(options)},
        'devices': list(devices), 'commands_enabled': commands,
    }
    # only the sections of listed devices: a key of another would stop the bridge (exit 2)
    if 'ams' in devices:
        params['ams'] = {'bank_count': banks}
    if 'evms3' in devices:
        params['evms3'] = {'bms12_modules': modules}
    if commands:
        params['commands_allowed'] = True
    for name, section in (sections or {}).items():
        params['devices'].append(name)
        params[name] = section
    params.update(extra or {})
    with open(path, 'w', encoding='utf-8') as stream:
        yaml.safe_dump({'/**': {'ros__parameters': params}}, stream)
    return path


def percentile(values: Sequence[float], q: float) -> float:
    """Return the q-quantile (0..1) of values, nearest rank."""
    ordered = sorted(values)
    if not ordered:
        return float('nan')
    return ordered[min(len(ordered) - 1, max(0, int(round(q * (len(ordered) - 1)))))]


def parse_options(entries: Sequence[str]) -> dict[str, object]:
    """Parse key=value python-can options exactly as the bridge does."""
    from ams_can_bridge.can_io.config import parse_options as parse
    return parse(list(entries))
