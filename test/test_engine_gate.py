# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The command gate alone (engine/gate.py, no ROS): every frame the bridge sends passes it.

A fake bus (``shared.FakeBus``) stands in for CanIo: its state is set by the test,
``wait_connected`` waits on a condition the test signals, and it records what was sent.
Waits are bounded; where a test must know a thread is inside the gate it waits for that
(bus_waiters, an event), never for a time.
"""
from __future__ import annotations

import logging
import threading

import pytest

from ams_can_bridge.bus_state import BusState
from ams_can_bridge.engine.gate import BUS_WAIT_SLOTS, arming_refused, CommandGate
from ams_can_bridge.protocols.common import Frame
from shared import collecting_logger, FakeBus, Lines

WAIT = 5.0  # s: the bound of every wait in this file (never reached when the gate works)


def make_gate(*, allowed: bool = True, enabled: bool = True, connect_wait: float = 2.0,
              bus: FakeBus | None = None) -> tuple[CommandGate, FakeBus, Lines]:
    logger, lines = collecting_logger('test_engine_gate')
    gate = CommandGate('fake:0', allowed=allowed, connect_wait=connect_wait, logger=logger,
                       node_name='/car/bridge')
    bus = bus or FakeBus()
    gate.attach_bus(bus)
    assert gate.start_enabled(enabled) is None
    return gate, bus, lines


FRAME = Frame(0x506, b'')
OTHER = Frame(0x7FF, b'\x01')


# --- refusals -------------------------------------------------------------------------------
def test_disabled_gate_refuses_naming_commands_enabled_and_sends_nothing():
    gate, bus, _ = make_gate(enabled=False)
    ok, message = gate.transmit(FRAME)
    assert not ok and 'commands_enabled' in message and '/car/bridge' in message
    ok, message = gate.send_periodic(FRAME)
    assert not ok and 'commands_enabled' in message
    assert bus.sent == []


def test_enabling_without_allowed_is_refused_with_the_launch_wording():
    gate, bus, lines = make_gate(allowed=False, enabled=False)
    assert gate.start_enabled(True) == arming_refused()
    assert gate.set_enabled(True) == arming_refused()
    assert not gate.enabled and gate.changes == 0
    assert (logging.WARNING, f'refused: {arming_refused()}') in lines.lines
    assert not gate.transmit(FRAME)[0] and bus.sent == []
    assert 'commands_allowed is false' in gate.refusal('reset the SoC')


def test_a_closed_bus_is_named_shutting_down():
    gate, bus, _ = make_gate()
    gate.attach_bus(None)
    assert gate.transmit(FRAME) == (
        False, 'CAN bus fake:0 is closed: the bridge is shutting down')


def test_a_driver_failure_is_an_answer_not_an_exception():
    gate, bus, _ = make_gate()
    bus.fail = 'tx buffer full'
    ok, message = gate.transmit(FRAME)
    assert not ok and message == 'CAN send failed on fake:0: tx buffer full'


# --- the log line ---------------------------------------------------------------------------
def test_each_frame_of_a_call_is_logged_with_its_source_and_outcome():
    gate, bus, lines = make_gate()
    with gate.calling('bms16/reset_soc'):
        assert gate.transmit(Frame(0x506, b'\x01\xAB'))[0]
    assert gate.transmit(Frame(0x1806E5F4, b'', True), source='evms3/read_config')[0]
    gate.set_enabled(False)
    with gate.calling('bms16/power_off'):
        assert not gate.transmit(FRAME)[0]
    info = [text for level, text in lines.lines if level == logging.INFO]
    assert info[0] == 'bms16/reset_soc: 506#01AB sent'
    assert info[1] == 'evms3/read_config: 1806E5F4# sent'
    assert info[2].startswith('bms16/power_off: 506# NOT sent: commands are disabled')


def test_periodic_frames_and_frames_outside_a_call_are_not_logged():
    gate, bus, lines = make_gate()
    assert gate.send_periodic(FRAME)[0] and gate.transmit(OTHER)[0]
    assert [text for level, text in lines.lines if level == logging.INFO] == []
    assert bus.sent == [FRAME, OTHER]


# --- the bus wait ---------------------------------------------------------------------------
def test_a_call_waits_for_a_reopening_bus_then_sends():
    bus = FakeBus(BusState.RECONNECTING)
    gate, bus, _ = make_gate(bus=bus)
    result = {}
    thread = threading.Thread(target=lambda: result.update(r=gate.transmit(FRAME)), daemon=True)
    thread.start()
    assert wait_until(lambda: gate.bus_waiters() == 1)
    assert bus.sent == []
    bus.set_state(BusState.CONNECTED)
    thread.join(WAIT)
    assert result['r'][0] and bus.sent == [FRAME]


def test_periodic_sends_never_wait_for_the_bus():
    gate, bus, _ = make_gate(bus=FakeBus(BusState.RECONNECTING))
    bus.fail = 'not connected'
    ok, message = gate.send_periodic(FRAME)  # at once: the test would hang otherwise
    assert not ok and 'not connected' in message and gate.bus_waiters() == 0


def test_at_most_bus_wait_slots_calls_wait_a_further_one_fails_at_once():
    gate, bus, _ = make_gate(bus=FakeBus(BusState.RECONNECTING), connect_wait=30.0)
    results: list[tuple[bool, str]] = []
    threads = [threading.Thread(target=lambda: results.append(gate.wait_for_bus()),
                                daemon=True)
               for _ in range(BUS_WAIT_SLOTS)]
    for thread in threads:
        thread.start()
    assert wait_until(lambda: gate.bus_waiters() == BUS_WAIT_SLOTS)
    ok, message = gate.wait_for_bus()
    assert not ok and f'{BUS_WAIT_SLOTS} commands already wait for it' in message
    # a disarm ends every wait at once (the listeners and the waits both follow it)
    gate.set_enabled(False)
    for thread in threads:
        thread.join(WAIT)
    assert [m for _, m in results] == [
        'commands_enabled was set to false while waiting for the CAN bus'] * BUS_WAIT_SLOTS
    assert gate.bus_waiters() == 0


def test_the_wait_is_bounded_by_connect_wait_and_the_commands_limit():
    gate, bus, _ = make_gate(bus=FakeBus(BusState.ERROR), connect_wait=0.2)
    bus.reason = 'no such device'
    ok, message = gate.wait_for_bus(limit=0.05)
    assert not ok and message == ('CAN bus fake:0 is not connected (error: no such device) '
                                  'after waiting 0.05 s (can.connect_wait 0.2 s, command '
                                  'timeout 0.05 s)')
    gate.connect_wait = 0.0
    ok, message = gate.wait_for_bus()
    assert not ok and 'can.connect_wait is 0: commands do not wait' in message


# --- batches ------------------------------------------------------------------------------
def test_a_batch_is_never_interleaved_with_another_calls_frame():
    gate, bus, _ = make_gate()
    inside, release = threading.Event(), threading.Event()

    def paced() -> None:
        with gate.batch():
            gate.transmit(Frame(36, b''), wait=False)
            inside.set()
            release.wait(WAIT)  # the pause between two frames of the batch
            gate.transmit(Frame(32, b''), wait=False)
    writer = threading.Thread(target=paced, daemon=True)
    writer.start()
    assert inside.wait(WAIT)
    other = threading.Thread(target=lambda: gate.transmit(Frame(38, b'')), daemon=True)
    other.start()
    # the other call cannot send while the batch holds the lock; it is sent after the batch
    assert not wait_until(lambda: len(bus.sent) > 1, 0.2)
    # ... but the heartbeat is never held up by a batch's pacing
    assert gate.send_periodic(Frame(0x305, b'\x00'))[0]
    release.set()
    writer.join(WAIT)
    other.join(WAIT)
    assert [f.arbitration_id for f in bus.sent] == [36, 0x305, 32, 38]


# --- listeners ----------------------------------------------------------------------------
def test_listeners_hear_every_change_before_set_enabled_returns():
    gate, bus, lines = make_gate(enabled=False)
    heard: list[bool] = []
    gate.add_listener(heard.append)
    assert gate.set_enabled(True, how='by test') is None
    assert gate.set_enabled(True) is None  # no change: nobody told, nothing counted
    assert gate.set_enabled(False) is None
    assert heard == [True, False] and gate.changes == 2
    warnings = [text for level, text in lines.lines if level == logging.WARNING]
    assert warnings == ['commands_enabled false -> true (by test): commands ENABLED, the '
                        'bridge may transmit',
                        'commands_enabled true -> false: commands disabled, listen only']
    gate.remove_listener(heard.append)
    gate.set_enabled(True)
    assert heard == [True, False]


def test_a_periodic_sender_stopped_by_the_listener_sends_nothing_after_the_disarm():
    gate, bus, _ = make_gate()
    stop = threading.Event()
    gate.add_listener(lambda enabled: None if enabled else stop.set())

    def heartbeat() -> None:
        while not stop.wait(0.005):
            gate.send_periodic(FRAME)
    thread = threading.Thread(target=heartbeat, daemon=True)
    thread.start()
    assert wait_until(lambda: len(bus.sent) >= 3)
    gate.set_enabled(False)  # returns after a send in flight; none goes out after it
    count = len(bus.sent)
    thread.join(WAIT)
    assert not thread.is_alive() and len(bus.sent) == count


@pytest.mark.parametrize('enabled', [True, False])
def test_properties_follow_set_enabled(enabled):
    gate, _, _ = make_gate(enabled=not enabled)
    gate.set_enabled(enabled)
    assert gate.enabled is enabled and gate.allowed is True


def wait_until(predicate, timeout: float = WAIT) -> bool:
    """Poll predicate until true or timeout s (bounded); return its last value."""
    done = threading.Event()
    deadline = timeout
    step = 0.002
    while deadline > 0:
        if predicate():
            return True
        done.wait(step)
        deadline -= step
    return bool(predicate())
