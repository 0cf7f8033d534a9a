# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Which parameter sets the running bridge allows, what they change, and a command call's answer.

engine/param_sets.py and engine/commands.py without rclpy: the node asks them on every set of
a parameter and every command service call (test_bridge_param_service.py,
test_bridge_lifecycle.py and test_bridge_command_gate.py drive the same rules through ROS).
"""
from __future__ import annotations

from contextlib import contextmanager
import logging
from types import SimpleNamespace

import pytest

from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.commands import Command, EXCHANGE, TRIGGER
from ams_can_bridge.engine.commands import Pipeline
from ams_can_bridge.engine.gate import arming_refused, CommandGate
from ams_can_bridge.engine.param_sets import (apply_set, device_changes, INACTIVE_REFUSAL,
                                              RUN_TIME_SET, set_refusal)
from ams_can_bridge.offline.params_file import FileParams


class Lines:
    """A logger that keeps (level, message), as the node's rclpy logger would print them."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def info(self, message: str) -> None:
        self.lines.append(('INFO', message))

    def warning(self, message: str) -> None:
        self.lines.append(('WARN', message))

    def error(self, message: str) -> None:
        self.lines.append(('ERROR', message))


class GateLog(logging.Handler):
    def __init__(self) -> None:
        super().__init__()
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


def make_gate(allowed: bool) -> tuple[CommandGate, GateLog]:
    logger = logging.getLogger(f'test_bridge_param_sets.{id(object())}')
    handler = GateLog()
    logger.addHandler(handler)
    logger.setLevel(logging.DEBUG)
    return CommandGate('virtual:x', allowed=allowed, connect_wait=0.0, logger=logger), handler


@pytest.fixture
def devices():
    names = ['ams', 'bms16']
    params = FileParams({'devices': names, 'ams.type': 'ams', 'bms16.type': 'bms16'})
    return DeviceSet(names, params.declare).devices


def refusal(name, value, gate, devices, active=True, log=None):
    return set_refusal(name, value, gate=gate, devices=devices, active=active,
                       log=log or Lines())


# --- which sets are allowed -------------------------------------------------------------------
def test_arming_without_commands_allowed_is_refused_and_logged(devices):
    gate, _ = make_gate(allowed=False)
    log = Lines()
    assert refusal('commands_enabled', True, gate, devices, log=log) == arming_refused()
    assert log.lines == [('WARN', f'refused: {arming_refused()}')]
    assert refusal('commands_enabled', False, gate, devices) is None  # disarming: always


def test_arming_an_inactive_bridge_is_refused_naming_the_lifecycle(devices):
    gate, _ = make_gate(allowed=True)
    assert refusal('commands_enabled', True, gate, devices, active=False) == INACTIVE_REFUSAL
    assert INACTIVE_REFUSAL == ('commands_enabled = true refused: the bridge is inactive '
                                '(lifecycle): activate it first (ros2 lifecycle set '
                                '/ams_can_bridge activate)')
    assert refusal('commands_enabled', True, gate, devices, active=True) is None
    assert refusal('commands_enabled', False, gate, devices, active=False) is None


def test_a_device_key_is_the_device_s_to_judge(devices):
    gate, _ = make_gate(allowed=True)
    reason = refusal('ams.bank_count', 9, gate, devices)
    assert reason is not None and reason == devices['ams'].config_reason('bank_count', 9)
    assert reason.startswith('ams.bank_count')
    assert refusal('ams.bank_count', 3, gate, devices) is None
    # not a device's key: nothing here to judge (ros/params.py checked the value)
    assert refusal('diagnostics_period', 0.5, gate, devices) is None
    assert refusal('ams', 3, gate, devices) is None


# --- what an accepted set changes -------------------------------------------------------------
def test_changes_are_grouped_per_device_instance(devices):
    changed = {'ams.bank_count': 2, 'ams.heartbeat_period': 0.1, 'bms16.stale_timeout': 2.0,
               'commands_enabled': True, 'other.key': 1}
    assert device_changes(changed, devices) == {
        'ams': {'bank_count': 2, 'heartbeat_period': 0.1}, 'bms16': {'stale_timeout': 2.0}}


def test_one_set_is_one_new_configuration_per_device(devices):
    gate, _ = make_gate(allowed=True)
    ams = devices['ams']
    before = ams.revision
    apply_set({'ams.bank_count': 2, 'ams.heartbeat_period': 0.1}, gate=gate, devices=devices,
              log=Lines())
    assert ams.bank_count == 2 and ams.config.heartbeat_period == 0.1
    assert ams.revision == before + 1  # one configuration swapped in, not two


def test_a_combination_a_device_refuses_is_logged_and_not_applied(devices):
    gate, _ = make_gate(allowed=True)
    log = Lines()
    apply_set({'ams.bank_count': 9}, gate=gate, devices=devices, log=log)
    assert devices['ams'].bank_count == 1
    assert len(log.lines) == 1 and log.lines[0][0] == 'ERROR'
    assert log.lines[0][1].startswith('ams: configuration change not applied: ams.bank_count')


def test_commands_enabled_goes_to_the_gate_naming_how_it_was_set(devices):
    gate, gate_log = make_gate(allowed=True)
    heard: list[bool] = []
    gate.add_listener(heard.append)
    apply_set({'commands_enabled': True}, gate=gate, devices=devices, log=Lines())
    assert gate.enabled and heard == [True]
    assert gate_log.messages == [f'commands_enabled false -> true ({RUN_TIME_SET}): commands '
                                 'ENABLED, the bridge may transmit']
    apply_set({'commands_enabled': False}, gate=gate, devices=devices, log=Lines())
    assert not gate.enabled and heard == [True, False] and gate.changes == 2


# --- a command service call (through the one pipeline, engine/commands.py) -----------------------
class NamingGate:
    """The gate's ``calling``: which service the thread answers meanwhile (commands on)."""

    enabled = True

    def __init__(self) -> None:
        self.source: str | None = None

    @contextmanager
    def calling(self, source: str):
        self.source = source
        try:
            yield
        finally:
            self.source = None


def call(callback, log: Lines, gate: NamingGate | None = None):
    """Run callback(request, response) as the pipeline runs the row ams/abort; the answer."""
    response = SimpleNamespace(success=False, message='')

    def run(port):
        answer = callback(SimpleNamespace(), response)
        return answer.success, answer.message
    row = Command('abort', 'abort', TRIGGER, 'run', EXCHANGE)
    pipeline = Pipeline(gate or NamingGate(), log)  # type: ignore[arg-type]
    response.success, response.message = pipeline.call(
        'ams', SimpleNamespace(run=run), row)  # type: ignore[arg-type]
    return response


def test_an_answer_is_logged_info_when_it_succeeded_warn_when_not():
    gate = NamingGate()
    seen = []

    def ok(request, response):
        seen.append(gate.source)
        response.success, response.message = True, 'sent'
        return response

    log = Lines()
    assert call(ok, log, gate).success and seen == ['ams/abort'] and gate.source is None
    assert log.lines == [('INFO', 'ams/abort: answered success=True: sent')]

    def no(request, response):
        response.message = 'commands_enabled is false'
        return response

    log = Lines()
    assert not call(no, log).success
    assert log.lines == [('WARN', 'ams/abort: answered success=False: '
                                  'commands_enabled is false')]


def test_a_callback_that_raises_is_an_internal_error_with_its_traceback():
    def bug(request, response):
        raise TypeError('unsupported operand')

    log = Lines()
    response = call(bug, log)
    assert not response.success
    assert response.message == ('ams/abort: internal error: TypeError: unsupported operand; '
                                'see the log')
    assert [level for level, _ in log.lines] == ['ERROR', 'WARN']
    assert log.lines[0][1].startswith('ams/abort: internal error:\nTraceback')
    assert 'TypeError: unsupported operand' in log.lines[0][1]
