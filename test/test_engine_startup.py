# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge's start-up decisions without ROS (engine/startup.py, engine/live.py).

What the node used to decide itself, now tested without rclpy: which bus settings stop the
bridge and in which words, how every problem of the start values becomes one error, which
keys are unknown and their nearest names, what the start summary says, how commands_enabled
given at launch arms the gate, and what the engine's view of the bus answers. The same texts
reach the user through the node (test_bridge_start_checks.py, test_bridge_lifecycle.py).
"""
from __future__ import annotations

import gc
import logging
import math
import weakref

import pytest

from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.can_io.core import STATE_CHANGE_FORMAT
from ams_can_bridge.device_set import DeviceSet, unknown_parameter_errors
from ams_can_bridge.devices.base import device_params
from ams_can_bridge.engine.gate import arming_refused
from ams_can_bridge.engine.live import BusView, CLOCK_PERIOD, live_engine, open_bus, settle_heap
from ams_can_bridge.engine.startup import (bus_settings, BusSettings, check_replay_clock,
                                           launch_gate, NO_DEVICES_WARNING, run_start_checks,
                                           start_error, start_summary)
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.offline.params_file import FileParams
from ams_can_bridge.parameters import BUS_PARAMS, NODE_PARAMS

BUS = {spec.key: spec.default for spec in BUS_PARAMS}
NODE = {spec.key: spec.default for spec in NODE_PARAMS}


def bus(**values) -> dict:
    return {**BUS, 'interface': 'virtual', 'channel': 'startup', **values}


def device_set(names: list[str], **values) -> DeviceSet:
    params = FileParams({'devices': names, **{f'{n}.type': n for n in names}, **values})
    return DeviceSet(names, params.declare)


# --- bus settings -------------------------------------------------------------------------
def test_usable_bus_settings_give_the_config_and_the_hardware_id():
    settings = bus_settings(bus(bitrate=500000))
    assert settings.errors == [] and settings.warnings == []
    assert settings.config is not None and settings.config.bitrate == 500000
    assert settings.hardware_id == 'virtual:startup' and not settings.replaying


def test_an_option_without_value_is_collected_naming_how_to_write_it():
    settings = bus_settings(bus(options=['timeout']))
    assert settings.config is None
    assert len(settings.errors) == 1
    assert settings.errors[0].startswith('can.options: ')
    assert settings.errors[0].endswith(' (write each option as key=value)')


def test_an_interface_that_can_never_work_is_collected_not_raised():
    settings = bus_settings(bus(interface='socketcann'))
    assert len(settings.errors) == 1
    assert "can.interface = 'socketcann' is not a python-can interface; did you mean " \
        "'socketcan'?" in settings.errors[0]


def test_what_a_replay_ignores_is_a_warning(tmp_path):
    log = tmp_path / 'x.asc'
    log.write_text('')
    settings = bus_settings(bus(interface='replay', channel=str(log), bitrate=500000))
    assert settings.errors == [] and settings.warnings == ['replay ignores can.bitrate']
    assert settings.replaying


def test_replay_clock_needs_a_replay():
    check_replay_clock(bus_settings(bus()))  # off: fine
    with pytest.raises(ConfigError) as info:
        check_replay_clock(bus_settings(bus(replay_clock=True)))
    assert str(info.value) == (
        "can.replay_clock is true but can.interface is 'virtual': /clock comes from a "
        "replayed log only (set can.interface to 'replay', or replay_clock to false)")


# --- every problem at once ------------------------------------------------------------------
def test_every_collected_problem_and_the_unknown_keys_are_one_error():
    errors: list[str] = []

    def configure() -> None:
        errors.extend(['a.x = 1 must be a string', 'b.y = 2 is out of range'])

    with pytest.raises(ConfigError) as info:
        run_start_checks(configure, errors, lambda: ['c: unknown parameter'])
    assert str(info.value) == ('3 parameters need a change:\n  - a.x = 1 must be a string\n'
                               '  - b.y = 2 is out of range\n  - c: unknown parameter')
    assert errors == []  # a later configure judges the values afresh


def test_the_unknown_keys_are_asked_even_when_configure_stops_early():
    errors: list[str] = []

    def configure() -> None:
        errors.append('a.x = 1 must be a string')
        raise ConfigError('devices overlap: a and b both use ID 0x10')

    with pytest.raises(ConfigError) as info:
        run_start_checks(configure, errors, lambda: ['c: unknown parameter'])
    assert str(info.value).splitlines() == [
        '3 parameters need a change:', '  - a.x = 1 must be a string',
        '  - c: unknown parameter', '  - devices overlap: a and b both use ID 0x10']


def test_a_stop_naming_a_collected_key_is_not_listed_twice():
    errors = ['a.type = 3 must be a string']
    error = start_error(errors, ParamError('a.type: unknown device type'))
    assert str(error) == 'a.type = 3 must be a string'
    assert type(error) is ConfigError
    alone = start_error([], ConfigError('devices = [a, a]: instance names must be unique'))
    assert str(alone) == 'devices = [a, a]: instance names must be unique'


def test_a_bug_in_configure_is_not_turned_into_a_setting_error():
    errors: list[str] = []

    def configure() -> None:
        raise TypeError('a bug')

    with pytest.raises(TypeError):
        run_start_checks(configure, errors, lambda: [])


def test_clean_start_values_raise_nothing():
    run_start_checks(lambda: None, [], lambda: [])


# --- unknown keys and their nearest names -----------------------------------------------------
def test_unknown_keys_are_named_with_the_nearest_declared_name():
    names = ['ams', 'ivt_s']
    declared = ['devices', 'commands_allowed', 'diagnostics_period']
    declared += [f'{n}.{spec.key}' for n, d in device_set(names).devices.items()
                 for spec in device_params(type(d))]
    given = {'devices': names, 'device': ['ams'], 'commands_alowed': True,
             'ams.bank_cont': 5, 'ivt_s.discharge_positiv': True, 'use_sim_time': False,
             'qos_overrides./x.publisher.depth': 5, 'bms.base_id': 10}
    assert unknown_parameter_errors(given, declared) == [
        'ams.bank_cont: unknown parameter of device ams (type ams); did you mean '
        '`ams.bank_count`?',
        "bms.base_id: belongs to no configured device: 'bms' is not in devices (devices lists "
        'ams, ivt_s); add bms to devices (with bms.type: ams or ivt_s or evms3 or bms16) or '
        'remove the key; did you mean `ams.base_id`?',
        'commands_alowed: unknown parameter (the bridge does not declare it); did you mean '
        '`commands_allowed`?',
        'device: unknown parameter (the bridge does not declare it); did you mean `devices`?',
        'ivt_s.discharge_positiv: unknown parameter of device ivt_s (type ivt_s); did you '
        'mean `ivt_s.discharge_positive`?']


# --- the start summary ------------------------------------------------------------------------
def test_the_summary_names_the_bus_the_gate_and_each_device_with_its_ids():
    settings = bus_settings(bus(bitrate=500000, fd=True, record='/tmp/rec.asc'))
    assert settings.config is not None
    devices = device_set(['bms16', 'evms3']).devices
    text, warning = start_summary(settings.config, settings.hardware_id, devices,
                                  enabled=False, allowed=False)
    assert warning is None
    lines = text.splitlines()
    assert lines[0] == ('CAN bus virtual:startup @ 500000 bit/s (FD), recording to '
                        '/tmp/rec.asc, listen only (commands_allowed is false: commands '
                        'cannot be enabled)')
    assert lines[1].startswith('  bms16 (bms16): 0x')
    assert lines[2].startswith('  evms3 (evms3): ') and lines[2].endswith(' (29-bit)')
    assert len(lines) == 3


def test_the_summary_says_commands_are_enabled_when_they_are():
    settings = bus_settings(bus())
    assert settings.config is not None
    text, _ = start_summary(settings.config, settings.hardware_id, {}, enabled=True,
                            allowed=True)
    assert text.splitlines()[0] == ('CAN bus virtual:startup, commands ENABLED '
                                    '(commands_enabled set at launch)')


def test_no_devices_is_said_in_the_summary_and_warned_with_how_to_set_them():
    settings = bus_settings(bus())
    assert settings.config is not None
    text, warning = start_summary(settings.config, settings.hardware_id, {}, enabled=False,
                                  allowed=True)
    assert text.splitlines() == ['CAN bus virtual:startup, listen only',
                                 '  no devices configured (set the devices parameter)']
    assert warning == NO_DEVICES_WARNING
    assert warning.startswith('devices is empty: the bridge decodes nothing')


# --- commands_enabled given at launch ---------------------------------------------------------
def gate_at_launch(autostart: bool | None, allowed: bool, enabled: bool):
    node = {**NODE, 'commands_allowed': allowed, 'commands_enabled': enabled}
    return launch_gate('virtual:x', node, bus(), autostart=autostart,
                       logger=logging.getLogger('test_engine_startup'), node_name='/b')


def test_enabled_at_launch_arms_at_once_with_autostart_and_at_activate_without():
    gate, later, refused = gate_at_launch(True, allowed=True, enabled=True)
    assert gate.enabled and not later and refused is None
    gate, later, refused = gate_at_launch(False, allowed=True, enabled=True)
    assert not gate.enabled and later and refused is None
    gate, later, refused = gate_at_launch(False, allowed=True, enabled=False)
    assert not gate.enabled and not later and refused is None


def test_enabled_at_launch_without_allowed_is_a_start_error():
    for autostart in (True, False):
        gate, later, refused = gate_at_launch(autostart, allowed=False, enabled=True)
        assert refused == arming_refused() and not gate.enabled and not later


# --- the engine's view of the bus -------------------------------------------------------------
OPEN = BusStatus(state=BusState.CONNECTED, reason='', frames_in=3, frames_out=0,
                 frames_dropped_tx=0, error_frames=0, reconnects=0, hardware_id='replay:x.asc')


class FakeBus:
    def __init__(self, stamp: float) -> None:
        self.last_stamp = stamp

    def status(self) -> BusStatus:
        return OPEN


def view(replaying: bool, bus_now) -> BusView:
    gate, _, _ = gate_at_launch(True, allowed=True, enabled=True)
    return BusView('replay:x.asc', replaying, gate, lambda: bus_now, wall=lambda: 42.0)


def test_a_closed_bus_is_stopped_and_stamps_follow_the_wall_clock():
    closed = view(True, None)
    status = closed.status()
    assert status.state == BusState.STOPPED and status.hardware_id == 'replay:x.asc'
    assert closed.now() == 42.0 and math.isnan(closed.clock_stamp())


def test_a_replay_stamps_with_the_log_time_once_a_frame_came():
    assert view(True, FakeBus(7.5)).now() == 7.5
    assert view(True, FakeBus(math.nan)).now() == 42.0  # no frame yet
    assert view(False, FakeBus(7.5)).now() == 42.0  # live: the host clock
    assert view(True, FakeBus(7.5)).clock_stamp() == 7.5
    assert view(True, FakeBus(7.5)).status() is OPEN


def test_the_bus_report_carries_the_command_keys():
    assert view(False, None).values() == {'commands_allowed': 'true',
                                          'commands_enabled': 'true',
                                          'commands_enabled changes': '0'}


class ListSink:
    def __init__(self) -> None:
        self.clocks: list[float] = []

    def battery(self, *args) -> None:
        pass

    def diagnostics(self, *args) -> None:
        pass

    def clock(self, stamp: float) -> None:
        self.clocks.append(stamp)


def test_the_live_engine_runs_its_schedule_and_clock_on_one_periodic_thread():
    gate, _, _ = gate_at_launch(True, allowed=True, enabled=False)
    replay = BusSettings(None, 'replay', 'replay:x', replay_clock=True)
    sink = ListSink()
    bus_now = FakeBus(3.25)
    engine, bus_view, periodic = live_engine(
        device_set(['bms16']), sink, replay, gate, lambda: bus_now, status_prefix='b',
        diagnostics_period=0.5, on_bus_status=lambda status: None,
        logger=logging.getLogger, thread_name='t')
    periods = [task[1] for task in periodic._tasks]
    assert periods == [period for period, _ in engine.schedule(0.5)] + [CLOCK_PERIOD]
    periodic._tasks[-1][2]()  # the /clock task: the log time of the last frame
    assert sink.clocks == [3.25] and bus_view.now() == 3.25
    assert engine.bus_report().values['commands_allowed'] == 'true'
    live = BusSettings(None, 'virtual', 'virtual:x', replay_clock=False)
    _, _, periodic = live_engine(
        device_set(['bms16']), sink, live, gate, lambda: None, status_prefix='b',
        diagnostics_period=0.5, on_bus_status=lambda status: None,
        logger=logging.getLogger, thread_name='t')
    assert len(periodic._tasks) == 3  # no /clock


def test_the_opened_bus_feeds_the_engine_and_logs_only_what_the_node_does_not():
    settings = bus_settings(bus())
    assert settings.config is not None
    gate, _, _ = gate_at_launch(True, allowed=True, enabled=False)
    devices = device_set(['bms16'])
    engine, _, _ = live_engine(devices, ListSink(), settings, gate, lambda: None,
                               status_prefix='b', diagnostics_period=1.0,
                               on_bus_status=lambda status: None,
                               logger=logging.getLogger, thread_name='t')
    logger = logging.getLogger('test_engine_startup.can_io')
    can_io = open_bus(settings.config, engine, devices, gate, logger)
    assert gate._bus is can_io and can_io._on_frame == engine.on_frame
    assert logger.level == logging.WARNING

    def record(msg: str) -> logging.LogRecord:
        return logging.LogRecord('x', logging.WARNING, 'f', 1, msg, None, None)
    assert not logger.filter(record(STATE_CHANGE_FORMAT))
    assert logger.filter(record('something else'))


class _Node:
    """An object in a reference cycle: only a full collection frees it."""

    def __init__(self) -> None:
        self.me = self


def test_settle_heap_freezes_what_configure_built_and_frees_it_after_cleanup():
    """What lives at configure leaves the full collections; after cleanup it is collected."""
    built = _Node()
    gone = weakref.ref(built)
    try:
        settle_heap()
        assert gc.get_freeze_count() > 0
        del built  # cleanup released it; frozen, a full collection does not see it
        gc.collect()
        assert gone() is not None
        settle_heap()  # the next configure: the earlier configure's garbage is collected
        assert gone() is None
    finally:
        gc.unfreeze()
