# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The CAN bus log lines: one per change of state, never one per reconnect attempt."""
from types import SimpleNamespace

from ams_can_bridge.ros.bus_log import BusStateLog


class Recorder:
    """A logger that keeps (level, text) lines."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def __getattr__(self, level: str):
        return lambda text: self.lines.append((level, text))


def run(states: list[tuple[str, str]]) -> list[tuple[str, str]]:
    log = Recorder()
    watch = BusStateLog(log, 'slcan:/dev/ttyACM0', '/dev/ttyACM0', 1.0)
    for state, reason in states:
        watch.update(SimpleNamespace(state=state, reason=reason))
    return [line for line in log.lines if line[0] != 'debug']


def test_adapter_missing_then_plugged_in():
    lines = run([('connecting', ''), ('error', 'No such file'), ('error', 'No such file'),
                 ('error', 'No such file'), ('connected', '')])
    assert lines == [
        ('error', 'CAN bus slcan:/dev/ttyACM0 cannot be opened (error: No such file); '
                  'retrying every 1 s'),
        ('info', 'CAN bus slcan:/dev/ttyACM0 connected')]


def test_lost_while_running_is_logged_once_then_reconnected():
    lines = run([('connecting', ''), ('connected', ''), ('reconnecting', 'gone'),
                 ('reconnecting', 'gone'), ('error', 'still gone'), ('connected', '')])
    assert [level for level, _ in lines] == ['info', 'error', 'info']
    assert 'lost (reconnecting: gone)' in lines[1][1]
    assert lines[2][1].startswith('CAN bus slcan:/dev/ttyACM0 reconnected after ')


def test_error_passive_and_replay_finished():
    lines = run([('connected', ''), ('error-passive', 'TEC 130'), ('connected', ''),
                 ('replay finished', '120 frames')])
    assert lines == [
        ('info', 'CAN bus slcan:/dev/ttyACM0 connected'),
        ('warning', 'CAN bus slcan:/dev/ttyACM0 error-passive: TEC 130'),
        ('info', 'replay of /dev/ttyACM0 finished')]
