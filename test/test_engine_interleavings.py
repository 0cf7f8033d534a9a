# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Random interleavings of everything a user and the world do to a bridge (issue 34).

Hypothesis's stateful testing drives ``interleavings.ModelBridge`` (the bridge below ROS on
a virtual bus with an adapter that can be unplugged, simulated devices that can go silent)
through sequences of: run-time parameter sets (the same or a new value, single, bursts,
thousands of copies, a huge list on a scalar), every command row of the AMS, IVT-S and
EVMS3 (in flight side by side), every valid lifecycle transition (shutdown included),
``commands_enabled`` toggles, bus unplug / replug and devices going silent; every step is
followed by the invariants of doc/failure_modes.md (``ModelBridge.check``). The ci profile
(test/conftest.py) is derandomized: the same sequences every run, under a minute in all;
``./dev bench --only interleavings --minutes N`` runs new ones for as long as asked.
"""
from __future__ import annotations

import time

import pytest
from hypothesis import HealthCheck, settings, strategies as st
from hypothesis.stateful import (initialize, precondition, rule,
                                 run_state_machine_as_test)

from interleavings import (Checked, gil_like_the_bridge, HEARTBEAT_SLACK, HUGE, MAX_PENDING,
                           ModelBridge, TRANSITIONS, VALUES)

SEQUENCES = 30  # the CI lane: sequences of STEPS steps (about 25 s in all)
STEPS = 40
CI_HEARTBEAT_SLACK = 0.1  # s: the CI lane's bound on a shared machine (run's docstring)


class Interleavings(Checked):
    """One random sequence against one model bridge (the module docstring)."""

    sequences = 0  # run so far in this process (the bench counts them)
    last_steps: list[str] = []  # the steps of the latest sequence (the bench prints them)

    def __init__(self) -> None:
        super().__init__()
        self.bridge = ModelBridge()
        Interleavings.sequences += 1
        Interleavings.last_steps = self.bridge.steps

    @initialize()
    def start_armed(self) -> None:
        # configured, active and armed: most sequences should start where it matters
        self.bridge.transition('configure')
        self.bridge.transition('activate')
        self.bridge.arm()
        self.bridge.bus_up()

    @rule(name=st.sampled_from(sorted(VALUES)), pick=st.integers(0, 2),
          copies=st.sampled_from([1, 1, 1, 30, 2000]))
    def set_parameter(self, name: str, pick: int, copies: int) -> None:
        values = VALUES[name]
        self.step(f'set {name} = {values[pick % len(values)]!r} x {copies}')
        self.bridge.set_param(name, values[pick % len(values)], copies)

    @rule(name=st.sampled_from(sorted(VALUES)), size=st.sampled_from(sorted(HUGE)))
    def set_a_huge_list_on_a_scalar(self, name: str, size: int) -> None:
        self.step(f'set {name} = a list of {size} values')
        started = time.monotonic()
        reason = self.bridge.huge_set(name, size)
        assert len(reason) < 300 and time.monotonic() - started < 1.0, reason[:300]

    @precondition(lambda self: self.bridge.commands is not None
                  and len(self.bridge.live_calls()) < MAX_PENDING)
    @rule(data=st.data())
    def call(self, data: st.DataObject) -> None:
        name, service, takes_data = data.draw(st.sampled_from(self.bridge.rows()))
        value = data.draw(st.booleans()) if takes_data else None
        self.step(f'call {name}/{service}' + ('' if value is None else f' {value}'))
        self.bridge.call(name, service, value)

    @rule()
    def arm(self) -> None:
        self.step('commands_enabled = true')
        self.bridge.arm()

    @rule()
    def disarm(self) -> None:
        self.step('commands_enabled = false')
        self.bridge.disarm(how='the model')

    @precondition(lambda self: self.bridge.state != 'finalized')
    @rule(data=st.data())
    def transition(self, data: st.DataObject) -> None:
        name = data.draw(st.sampled_from(TRANSITIONS[self.bridge.state]))
        self.step(f'lifecycle {name}')
        self.bridge.transition(name)


def run(sequences: int = SEQUENCES, steps: int = STEPS,
        heartbeat_slack: float = HEARTBEAT_SLACK, **options: object) -> None:
    """
    Run ``sequences`` random sequences of up to ``steps`` steps (the bench: more).

    ``heartbeat_slack``: s a heartbeat may be late beyond its period. The model's figure is
    20 ms (the bench checks it); the CI lane allows CI_HEARTBEAT_SLACK, as the live run:
    on 2 cores shared with other test runs (load 4-5) the OS alone delays a thread that
    long, whatever the bridge does.
    """
    ModelBridge.heartbeat_slack = heartbeat_slack
    with gil_like_the_bridge():
        run_state_machine_as_test(Interleavings, settings=settings(
            settings.default, max_examples=sequences, stateful_step_count=steps,
            deadline=None, suppress_health_check=list(HealthCheck), **options))


@pytest.mark.process  # the machine's canary (interleavings.Canary)
def test_no_invariant_breaks_under_random_interleavings():
    run(heartbeat_slack=CI_HEARTBEAT_SLACK)
