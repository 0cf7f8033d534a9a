# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The pack through the engine without ROS: member frames in, the pack's messages out."""
from __future__ import annotations

import logging
import math

import pytest

from ams_can_bridge.engine.core import Engine
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.engine.commands import Pipeline
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.sim.bms16 import Bms16Simulator
from ams_can_bridge.sim.evms3 import Evms3Simulator
from helpers import Clock
from pack_rig import build

DEVICES = ['bms16', 'evms3', 'pack']
BASE = {'devices': DEVICES, 'bms16.type': 'bms16', 'evms3.type': 'evms3',
        'pack.type': 'pack', 'pack.members': ['bms16', 'evms3'],
        'pack.max_charge_current': 40.0, 'pack.max_discharge_current': 80.0,
        'pack.max_voltage_difference': 1000.0, 'pack.max_cell_sum_difference': 1000.0}


def play(engine: Engine, clock: Clock, sims, start: float, seconds: float) -> float:
    t = start
    while t < start + seconds:
        clock.now = t
        for sim in sims:
            for frame in sim.tick(t):
                engine.on_frame(frame.arbitration_id, frame.data, frame.is_extended_id, t)
        t = round(t + 0.05, 6)
    return t


def test_member_reports_make_the_pack_by_the_table_and_a_stale_member_zeroes_the_limits():
    clock = Clock(0.0)
    engine, sink, _ = build(BASE, clock)
    bms16, evms3 = Bms16Simulator(send_sma=False, seed=1), Evms3Simulator()
    t = play(engine, clock, [bms16, evms3], 0.0, 3.0)
    (pack, _), (a, _), (b, _) = (sink.reports['pack'][-1], sink.reports['bms16'][-1],
                                 sink.reports['evms3'][-1])
    assert a.present and b.present and pack.present
    assert pack.voltage == (a.voltage + b.voltage) / 2  # parallel: the mean
    assert pack.current == a.current + b.current
    assert pack.cell_voltage == a.cell_voltage + b.cell_voltage
    values, _ = sink.figure_msgs['pack'][-1]
    assert set(values) == {'charge_current_limit', 'discharge_current_limit',
                           'time_to_empty', 'time_to_full'}
    assert (values['charge_current_limit'], values['discharge_current_limit']) == (40.0, 80.0)
    # one pack message per member report
    assert len(sink.reports['pack']) == len(sink.reports['bms16']) + len(sink.reports['evms3'])
    # the EVMS3 falls silent: its stale message names it to the pack, the limits go to 0
    t = play(engine, clock, [bms16], t, 6.0)
    engine.watch()
    pack, _ = sink.reports['pack'][-1]
    assert pack.present and math.isnan(pack.voltage)
    values, _ = sink.figure_msgs['pack'][-1]
    assert (values['charge_current_limit'], values['discharge_current_limit']) == (0.0, 0.0)
    status = dict(engine.statuses())['bridge: pack']
    assert status.level == 1 and 'evms3 is stale' in status.message
    # it comes back: the limits come back with it
    play(engine, clock, [bms16, evms3], t, 1.0)
    values, _ = sink.figure_msgs['pack'][-1]
    assert (values['charge_current_limit'], values['discharge_current_limit']) == (40.0, 80.0)


def test_an_msl_event_latches_and_clear_events_answers_without_commands_enabled():
    clock = Clock(0.0)
    # every cell above 1 V: the MSL of 1.2 V is passed at once, debounced 0.5 s
    params = dict(BASE, **{'pack.limits.cell_voltage_max': [1.0, 1.1, 1.2]})
    engine, sink, device_set = build(params, clock)
    bms16, evms3 = Bms16Simulator(send_sma=False, seed=1), Evms3Simulator()
    play(engine, clock, [bms16, evms3], 0.0, 3.0)
    status = dict(engine.statuses())['bridge: pack']
    assert status.level == 2
    assert 'raised at' in status.values['event MSL cell_voltage_max']
    values, _ = sink.figure_msgs['pack'][-1]
    assert (values['charge_current_limit'], values['discharge_current_limit']) == (0.0, 0.0)
    gate = CommandGate('virtual:x', allowed=False, connect_wait=0.1,
                       logger=logging.getLogger('test'))
    assert not gate.enabled
    pipeline = Pipeline(gate, _Log())
    row = device_set.devices['pack'].COMMANDS[0]
    ok, message = pipeline.call('pack', device_set.devices['pack'], row)
    assert not ok
    assert message.startswith('pack: still beyond: cell_voltage_max is ')
    assert 'beyond the MSL 1.2 V' in message


class _Log:
    def info(self, message): pass

    def warning(self, message): pass

    def error(self, message): pass


@pytest.mark.parametrize('change, words', [
    ({'pack.members': ['bms16', 'ghost']}, "'ghost' is not in devices"),
    ({'pack.members': ['bms16', 'bms16']}, 'listed twice'),
    ({'pack.members': ['bms16', 'pack']}, 'the pack itself'),
    ({'pack.members': []}, 'members is empty'),
    ({'pack.limits.temperature_max': [60.0, 50.0, 55.0]}, 'strictly increasing'),
    ({'pack.limits.cell_voltage_min': [3.0, 2.8]}, 'three numbers'),
    ({'pack.connection': 'diagonal'}, 'parallel, series'),
])
def test_a_wrong_pack_configuration_says_what_to_change(change, words):
    with pytest.raises((ConfigError, ParamError)) as error:
        build(dict(BASE, **change), Clock(0.0))
    assert words in str(error.value)


def test_members_listed_after_the_pack_or_not_batteries_are_refused():
    params = dict(BASE, devices=['bms16', 'pack', 'evms3'])
    with pytest.raises(ConfigError, match='comes after pack in devices'):
        build(params, Clock(0.0))
    params = dict(BASE, devices=['bms16', 'ivt', 'pack'], **{'ivt.type': 'ivt_s',
                                                             'pack.members': ['bms16', 'ivt']})
    with pytest.raises(ConfigError, match='of type ivt_s, not a battery'):
        build(params, Clock(0.0))
