# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The one command pipeline (engine/commands.py) and the device rows, without ROS.

Every service of every device type is a row (``Device.COMMANDS``); these tests walk the rows
through ``engine.commands.Commands`` on a gate with a recording bus (test_engine_gate's
``FakeBus``, the gate itself real), so each holds for every command at once: the refusal
while disabled, a bug answered as an internal error, the answer's log line, the periodic
senders following the gate.
"""
from __future__ import annotations

import logging
from pathlib import Path

import pytest

from ams_can_bridge import registry
from ams_can_bridge.bus_state import BusState
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.commands import Carried, Exchange, Frames, Local, Request
from ams_can_bridge.engine.commands import Commands, Pipeline
from ams_can_bridge.engine.gate import CommandGate
from shared import collecting_logger, FakeBus
from helpers import assert_ended, wait_for

REPO = Path(__file__).resolve().parent.parent
# every device type, both BMS16 variants: two bridges (the standard-form BMS16 speaks the
# EVMS3 protocol on its IDs, so it cannot share a bus with the EVMS3)
BRIDGES = (
    {'devices': ['ams', 'ivt_s', 'evms3', 'bms16', 'sma', 'dbc'],
     'ams.base_id': 0x400,  # the SMA keep-alive is 0x305, the AMS heartbeat at base + 5
     'dbc.dbc_file': str(REPO / 'msg_defs' / 'ams.dbc'),
     'dbc.mapping_file': str(REPO / 'config' / 'ams_dbc_mapping.yaml'),
     'sma.inverter_keepalive': True, 'ivt_s.check_config_at_start': True,
     'evms3.config_request': True, 'ams.charge_current_a': 10.0},
    {'devices': ['bms16'], 'bms16.variant': 'standard'},
)


def command_side(params, *, allowed=True, enabled=False, bus=None):
    """Build every instance of params, a real gate on a recording bus, the command side."""
    logger, lines = collecting_logger('test_engine_commands')
    gate = CommandGate('fake:0', allowed=allowed, connect_wait=0.5, logger=logger,
                       node_name='/car/bridge')
    bus = bus or FakeBus()
    gate.attach_bus(bus)
    assert gate.start_enabled(enabled) is None
    devices = DeviceSet(params['devices'], lambda name, spec: params.get(name, spec.default))
    commands = Commands(gate, devices.devices, logger)
    return commands, bus, lines


def every_call(commands):
    """Yield (name, row, data) for every service of the bridge, both values of a SetBool."""
    for name, row in commands.rows():
        for data in ((True, False) if row.request is Request.SET_BOOL else (None,)):
            yield name, row, data


@pytest.mark.parametrize('allowed', [True, False])
def test_every_service_of_every_device_answers_alike_while_disabled_and_sends_nothing(
        allowed):
    services, answered = set(), 0
    for params in BRIDGES:
        commands, bus, lines = command_side(params, allowed=allowed)
        try:
            for name, row, data in every_call(commands):
                services.add((params.get(f'{name}.variant', name), row.service))
                ok, message = commands.call(name, row.service, data)
                # one answer, worded by the gate, for every command: the parameter(s) to set
                assert (ok, message) == (
                    False, f'{name}: {commands.gate.refusal(row.words(data))}')
                assert 'nothing was sent' in message
                assert ('commands_allowed is false' in message) is not allowed
            assert bus.sent == []
            # each refusal is answered and logged as refused (WARN)
            answered += len([w for w in lines.at(logging.WARNING)
                             if 'answered success=False' in w])
            # the senders with threads of their own never started either
            for name, senders in commands.senders.items():
                assert [s.label for s in senders if s.thread is not None] == [], name
            if 'ivt_s' in commands.devices:
                assert commands.start_checks['ivt_s'].outcome is None
        finally:
            commands.close()
    # every command row of every device type and variant (the descriptors' rows; a variant
    # other than the default under its own name) was called, and nothing else; pack: its
    # members' reports, not a bus, so it is not in BRIDGES (its row: test_pack_*)
    rows = [(name if variant is None or variant == found.variant_names[0] else variant, row)
            for name, found in registry.DESCRIPTORS.items() if name != 'pack'
            for variant in (found.variant_names or (None,)) for row in found.commands(variant)]
    assert services == {(label, row.service) for label, row in rows}
    assert answered == sum(2 if row.request is Request.SET_BOOL else 1 for _, row in rows)
    assert answered == 30  # 28 services, two of them SetBool (true and false)


def test_every_row_names_a_method_of_its_device_and_a_policy():
    types = [found.device_class(variant) for found in registry.DESCRIPTORS.values()
             for variant in (found.variant_names or (None,))]
    for cls in types:
        services = [row.service for row in cls.COMMANDS]
        assert len(services) == len(set(services)), cls
        for row in cls.COMMANDS:
            assert callable(getattr(cls, row.build, None)), (cls, row)
            assert isinstance(row.policy, (Frames, Exchange, Carried, Local)), (cls, row)
            assert row.what and (row.request is Request.SET_BOOL) == bool(row.what_false)
            if isinstance(row.policy, Frames) and row.policy.paced:
                assert getattr(cls, 'CONFIG_FRAME_GAP', 0) > 0, (cls, row)


def test_a_refusal_is_the_answer_and_a_bug_an_internal_error_with_its_traceback():
    commands, bus, lines = command_side({'devices': ['bms16', 'ams']}, enabled=True)
    try:
        # a deliberate refusal (RefusedCommand): the answer, nothing sent
        ok, message = commands.call('ams', 'set_charge_current')
        assert not ok and message == (
            'ams: cannot set the charge current: ams.charge_current_a is not set: set it to '
            'the charge current in A (0..25.5 in steps of 0.1); nothing was sent')
        device = commands.devices['bms16']

        def broken():
            raise TypeError('unsupported operand')
        device.reset_soc_frame = broken  # the pipeline looks the builder up at each call
        ok, message = commands.call('bms16', 'reset_soc')
        assert not ok and message == ('bms16/reset_soc: internal error: TypeError: '
                                      'unsupported operand; see the log')
        [error] = lines.at(logging.ERROR)
        assert error.startswith('bms16/reset_soc: internal error:\nTraceback')
        assert "raise TypeError('unsupported operand')" in error
        assert [f.arbitration_id for f in bus.sent
                if f.arbitration_id != 0x305] == []  # only the heartbeat went out
        del device.reset_soc_frame
        ok, message = commands.call('bms16', 'reset_soc')
        assert ok and message == 'bms16: reset the SoC: sent ID 507 (0x1FB) [no data]'
        info = lines.at(logging.INFO)
        # the frame's log line names the service; the answer is logged once, at INFO
        assert 'bms16/reset_soc: 1FB# sent' in info
        assert info.count(f'bms16/reset_soc: answered success=True: {message}') == 1
    finally:
        commands.close()


def test_a_frame_refused_midway_ends_the_call_and_says_what_was_sent():
    commands, bus, _ = command_side({'devices': ['bms16'], **{
        f'bms16.config.{k}': v for k, v in {
            'cells': 14, 'pack_capacity_ah': 100, 'soc_warning_pct': 20,
            'full_voltage_v': 58.0, 'warn_current_a': 150, 'trip_current_a': 300.0,
            'temperature_limit_c': 60, 'min_cell_v': 2.8, 'max_cell_v': 3.65,
            'hysteresis_v': 0.1, 'balance_v': 3.5, 'shunt_size_a': 200}.items()}},
        enabled=True)
    try:
        sends = []

        def second_fails(frame):
            sends.append(frame)
            if len(sends) == 2:
                bus.fail = 'tx buffer full'
        bus.before_send = second_fails
        ok, message = commands.call('bms16', 'write_config')
        assert not ok
        assert message == ('bms16: write the configuration failed at ID 505 (0x1F9) '
                           '[49 02 46 02]: CAN send failed on fake:0: tx buffer full; sent '
                           'before it: ID 504 (0x1F8) [0E 0A 14 3A 0F 1E 3C 38]; not sent: ID 505')
        assert [f.arbitration_id for f in bus.sent] == [504]
    finally:
        commands.close()


def test_senders_armed_at_launch_start_when_the_bus_connects_and_a_call_starts_them_at_once():
    bus = FakeBus(BusState.CONNECTING)
    commands, _, lines = command_side({'devices': ['ams', 'sma'], 'ams.base_id': 0x400,
                                       'sma.inverter_keepalive': True,
                                       'ams.heartbeat_period': 0.01}, enabled=True, bus=bus)
    ams, sma = commands.devices['ams'], commands.devices['sma']
    try:
        # armed at launch, the bus still opening: nothing runs, nothing is dropped
        assert not ams.master.running and not sma.keepalive.running
        assert not ams.charger.armed and bus.sent == []
        info = lines.at(logging.INFO)
        assert 'ams: the heartbeat starts when the CAN bus is connected' in info
        assert 'sma: the inverter keep-alive starts when the CAN bus is connected' in info
        # a call that waits for the bus arms its device's senders as soon as it connects
        # (not when the start's own wait wakes up): the START is repeated, not refused
        bus.set_state(BusState.CONNECTED)
        ok, message = commands.call('ams', 'start_charging')
        assert ok and 'repeated every 100 ms' in message, message
        assert ams.master.running
        wait_for(lambda: sma.keepalive.running, 5.0, 'the keep-alive to start')
        wait_for(lambda: len([f for f in bus.sent if f.arbitration_id == 0x405]) >= 3, 5.0,
                 'heartbeats')
        heartbeat, repeat, keepalive = (ams.master.thread, ams.charger.thread,
                                        sma.keepalive.thread)
        # a disarm stops all three before set_enabled returns; nothing goes out after it
        assert commands.gate.set_enabled(False) is None
        count = len(bus.sent)
        for thread, what in ((heartbeat, 'heartbeat'), (repeat, 'repeat'),
                             (keepalive, 'keep-alive')):
            assert_ended(thread, what)
        assert len(bus.sent) == count
        assert not ams.charger.armed
    finally:
        commands.close()


def test_disarmed_before_the_bus_connects_nothing_ever_starts():
    bus = FakeBus(BusState.CONNECTING)
    commands, _, _ = command_side({'devices': ['ams']}, enabled=True, bus=bus)
    try:
        assert commands.gate.set_enabled(False) is None
        bus.set_state(BusState.CONNECTED)
        commands.fire('ams')  # the start was cancelled: nothing left to fire
        assert not commands.devices['ams'].master.running and bus.sent == []
    finally:
        commands.close()


def test_close_stops_every_sender_and_says_so_once():
    commands, bus, lines = command_side({'devices': ['ams']}, enabled=True)
    master = commands.devices['ams'].master
    wait_for(lambda: bus.sent, 5.0, 'a heartbeat')
    thread = master.thread
    commands.close()
    count = len(bus.sent)
    assert_ended(thread, 'the heartbeat')
    assert len(bus.sent) == count
    assert lines.at(logging.INFO).count('ams: heartbeat stopped (the bridge is shutting '
                                        'down)') == 1


def test_a_pipeline_without_a_node_refuses_to_set_parameters():
    logger, _ = collecting_logger('test_engine_commands')
    gate = CommandGate('fake:0', allowed=True, connect_wait=0.0, logger=logger)
    assert Pipeline(gate, logger).set_config('evms3', {'config.cells': 12}) == (
        False, 'this bridge has no parameters to set')
