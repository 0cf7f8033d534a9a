# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The interleavings against the real node (issue 34, the systematic part, the live run).

A smaller run of the state machine of test/test_engine_interleavings.py on a real ``BridgeNode``
(``command_rig.Rig``) over the model's unpluggable virtual adapter, every request through
ROS: parameter sets and ``commands_enabled`` through the parameter service, transitions
through ``change_state``, every command row through its service. The same invariants,
with the live bounds of a loaded 2-core machine: heartbeats at most one period + 100 ms
apart, a disarm answered within ``DISARM_BOUND`` through ROS, every call answered, the
node and its executor alive.
"""
from __future__ import annotations

import time
from typing import Any

from hypothesis import HealthCheck, settings, strategies as st
import pytest
from hypothesis.stateful import precondition, rule, run_state_machine_as_test
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from std_srvs.srv import SetBool, Trigger

from command_rig import Rig
from interleavings import (Checked, CONNECT_WAIT, gil_like_the_bridge, InvariantBroken,
                           MAX_PENDING, ModelBridge, Pending, RECONNECT, TRANSITIONS, VALUES)

NODE = '/ams_can_bridge'
SEQUENCES = 12  # the CI lane: a few short sequences (about 20 s in all)
STEPS = 20
IDS = {'configure': Transition.TRANSITION_CONFIGURE,
       'activate': Transition.TRANSITION_ACTIVATE,
       'deactivate': Transition.TRANSITION_DEACTIVATE,
       'cleanup': Transition.TRANSITION_CLEANUP}
SHUTDOWN = {'unconfigured': Transition.TRANSITION_UNCONFIGURED_SHUTDOWN,
            'inactive': Transition.TRANSITION_INACTIVE_SHUTDOWN,
            'active': Transition.TRANSITION_ACTIVE_SHUTDOWN}


class LiveBridge(ModelBridge):
    """The model's wire, simulators and invariants around a real node."""

    heartbeat_slack = 0.1  # s: the live bound on a loaded 2-core machine (issue 34)
    disarm_bound = 0.5  # s through ROS, the client in this same process (the model: 0.1)

    def __init__(self) -> None:
        super().__init__('live')
        self.rig = Rig({'devices': ['ams', 'ivt_s', 'evms3'], 'commands_allowed': True,
                        'commands_enabled': True, 'can.interface': 'pluggable',
                        'can.connect_wait': CONNECT_WAIT, 'can.reconnect_period': RECONNECT,
                        'evms3.config_request': True, 'ams.bank_count': 3,
                        **{name: values[0] for name, values in VALUES.items()},
                        'ams.heartbeat_period': 0.05}, channel=self.channel)
        self.state, self.enabled, self.silent_mark = 'active', True, None
        self._sent_ids()
        self.bus_up()

    def _sent_ids(self) -> None:
        self.sent_ids = {key for device in self.rig.node.devices.values()
                         for key in device.sent_ids()}

    def bus_connected(self) -> bool:
        can_io = self.rig.node.can_io
        return can_io is not None and can_io.status().connected

    def _set(self, *params: Parameter) -> list[Any]:
        return self.rig.call(SetParameters, f'{NODE}/set_parameters', timeout=60.0,
                             parameters=[p.to_parameter_msg() for p in params]).results

    def set_param(self, name: str, value: Any, copies: int = 1) -> str | None:
        results = self._set(*[Parameter(name, value=value)] * copies)
        refused = next((r.reason for r in results if not r.successful), None)
        if refused is None and name == 'ams.heartbeat_period':
            self.window_periods.add(float(value))
        if refused is None:
            self.values[name] = value
        return refused

    def huge_set(self, name: str, size: int) -> str:
        [result] = self._set(Parameter(name, value=[0.5] * size))
        if result.successful:
            raise InvariantBroken(f'{name}: a list of {size} values was accepted')
        return str(result.reason)

    def arm(self) -> None:
        if self.set_param('commands_enabled', True) is None:
            self.enabled = True
            self.silent_mark = None
            self._window(self.plugged)

    def disarm(self, how: str = '') -> None:
        started = time.monotonic()
        [result] = self._set(Parameter('commands_enabled', value=False))
        took = time.monotonic() - started
        self.disarms.append(took)
        self.enabled = False
        self._window(False)
        self._quiet()
        if not result.successful or took > self.disarm_bound:
            raise InvariantBroken(f'the disarm: {result.reason or "answered"} after '
                                  f'{took * 1000:.0f} ms, {len(self.live_calls())} call(s) in '
                                  'flight')

    def transition(self, name: str) -> None:
        assert name in TRANSITIONS[self.state], (self.state, name)
        if name in ('cleanup', 'shutdown'):
            time.sleep(0.3)  # requests still in DDS reach their callbacks (ROS's to lose)
        transition = SHUTDOWN[self.state] if name == 'shutdown' else IDS[name]
        ok = self.rig.call(ChangeState, f'{NODE}/change_state', timeout=30.0,
                           transition=Transition(id=transition)).success
        if not ok:
            raise InvariantBroken(f'{name} from {self.state} failed')
        self.state = {'configure': 'inactive', 'activate': 'active', 'deactivate': 'inactive',
                      'cleanup': 'unconfigured', 'shutdown': 'finalized'}[name]
        if name == 'configure':
            self._sent_ids()
        if name != 'configure' and name != 'activate':
            self.enabled = False
            self._window(False)
            self._quiet()

    def rows(self) -> list[tuple[str, str, bool]]:
        commands = self.rig.node.commands
        if commands is None or self.state not in ('inactive', 'active'):
            return []
        return [(name, row.service, row.request.name == 'SET_BOOL')
                for name, row in commands.rows()]

    def call(self, name: str, service: str, data: bool | None) -> None:
        kind, fields = (SetBool, {'data': bool(data)}) if data is not None else (Trigger, {})
        rig = self.rig

        def run() -> tuple[bool, str]:
            answer = rig.call(kind, f'/{name}/{service}', timeout=30.0, **fields)
            return answer.success, answer.message
        bound = 30.0  # every call of these devices answers well within it (see the model)
        self.pending.append(Pending(f'{name}/{service}', run, bound))

    def check(self) -> None:
        super().check()
        if self.rig.failures:
            raise InvariantBroken(f'the node failed: {self.rig.failures}')
        if self.rig.executor._is_shutdown or not self.rig.context.ok():
            raise InvariantBroken('the node exited')

    def close(self) -> None:
        for pending in self.pending:
            pending.thread.join(35.0)
        self.rig.close()
        self.state = 'finalized'
        super().close()


class LiveInterleavings(Checked):
    """A random sequence against a real node (module docstring)."""

    def __init__(self) -> None:
        super().__init__()
        self.bridge = LiveBridge()

    @precondition(lambda self: self.bridge.state != 'finalized')
    @rule(name=st.sampled_from(sorted(VALUES)), pick=st.integers(0, 2),
          copies=st.sampled_from([1, 1, 200]))
    def set_parameter(self, name: str, pick: int, copies: int) -> None:
        values = VALUES[name]
        self.bridge.set_param(name, values[pick % len(values)], copies)

    @precondition(lambda self: self.bridge.state != 'finalized')
    @rule()
    def set_a_long_list_on_a_scalar(self) -> None:
        self.bridge.huge_set('ams.command_timeout', 10_000)

    @precondition(lambda self: bool(self.bridge.rows())
                  and len(self.bridge.live_calls()) < MAX_PENDING)
    @rule(data=st.data())
    def call(self, data: st.DataObject) -> None:
        name, service, takes_data = data.draw(st.sampled_from(self.bridge.rows()))
        self.bridge.call(name, service, data.draw(st.booleans()) if takes_data else None)

    @precondition(lambda self: self.bridge.state != 'finalized')
    @rule()
    def arm(self) -> None:
        self.bridge.arm()

    @precondition(lambda self: self.bridge.state != 'finalized')
    @rule()
    def disarm(self) -> None:
        self.bridge.disarm()

    @precondition(lambda self: self.bridge.state != 'finalized')
    @rule(data=st.data())
    def transition(self, data: st.DataObject) -> None:
        self.bridge.transition(data.draw(st.sampled_from(TRANSITIONS[self.bridge.state])))


@pytest.mark.ros  # each sequence starts its own Rig (out of the lanes' sight)
@pytest.mark.process  # the machine's canary (interleavings.Canary)
def test_no_invariant_breaks_on_the_real_node():
    with gil_like_the_bridge():
        run_state_machine_as_test(LiveInterleavings, settings=settings(
            settings.default, max_examples=SEQUENCES, stateful_step_count=STEPS,
            deadline=None, suppress_health_check=list(HealthCheck)))
