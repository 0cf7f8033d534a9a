# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Hostile parameter sets through the real parameter services (issue 26, points 1, 2, 3).

Point 2: PARAMETER_NOT_SET would make rclpy undeclare a live parameter (the heartbeat's bank
count dropped to 1, the value could not be set again until a restart); it is refused for
every declared parameter, naming it, with a log line. Point 1: a request rclpy cannot even
read (a parameter type that does not exist) is answered, never fatal. Point 3: an array
longer than its documented maximum is refused on its length, before any element is looked
at (the disarm's timing with a 3,000,000-value set in flight is measured in
bench/bench_disarm.py, not asserted here).
"""
from __future__ import annotations

import array

import pytest
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterValue
from rcl_interfaces.srv import SetParameters, SetParametersAtomically
from rclpy.parameter import Parameter

from ams_can_bridge.errors import ParamError
from ams_can_bridge.parameters import coerce, MAX_BUS_OPTIONS, MAX_DEVICES, NODE_PARAMS
from ams_can_bridge.protocols.ams import AmsCodec, DEFAULT_BASE_ID as AMS_BASE
from shared import every_device

NODE = '/ams_can_bridge'
HEARTBEAT = AMS_BASE + 5
CELLS = 'evms3.config.cells_per_module'
NO_SUCH_TYPE = 42  # rcl_interfaces/ParameterType ends at 9


def armed_every_device() -> dict:
    return {**every_device(), 'commands_allowed': True, 'commands_enabled': True,
            'ams.bank_count': 5}


def set_messages(rig, *parameters: ParameterMsg) -> list:
    return rig.call(SetParameters, f'{NODE}/set_parameters', parameters=list(parameters),
                    timeout=60.0).results


def bank_counts_since(rig, mark: int) -> list[int]:
    codec = AmsCodec()
    return [codec.decode(HEARTBEAT, f.data).bank_count
            for _, f in rig.capture.since(mark, HEARTBEAT)]


def test_not_set_is_refused_for_every_declared_parameter_naming_it(rig_factory, capfd):
    rig = rig_factory(armed_every_device())
    names = sorted(rig.node._parameters)
    assert {'ams.bank_count', 'ams.heartbeat_period', 'ams.command_timeout',
            'evms3.read_timeout', 'evms3.config.pack_capacity_ah', 'commands_enabled'} <= set(
        names)
    before = {name: rig.node._parameters[name].type_ for name in names}
    results = set_messages(rig, *(ParameterMsg(name=name) for name in names))  # type NOT_SET
    assert len(results) == len(names)
    for name, result in zip(names, results):
        assert not result.successful, f'{name} was unset'
        assert name in result.reason and 'cannot be unset' in result.reason, result.reason
        assert rig.node.has_parameter(name), f'{name} was undeclared'
        assert rig.node._parameters[name].type_ == before[name], name
    err = capfd.readouterr().err
    for name in ('ams.bank_count', 'commands_enabled', 'evms3.config.pack_capacity_ah'):
        assert any(line.startswith('[WARN]') and f'refused: {name} cannot be unset' in line
                   for line in err.splitlines()), (name, err[-2000:])
    # the heartbeat still carries the bank count, and it can still be set
    mark = rig.capture.mark()
    rig.wait(lambda: len(bank_counts_since(rig, mark)) >= 3, what='3 more heartbeats')
    assert set(bank_counts_since(rig, mark)) == {5}
    assert rig.set_param('ams.bank_count', 4).successful
    mark = rig.capture.mark()
    rig.wait(lambda: 4 in bank_counts_since(rig, mark), what='a heartbeat with 4 banks')
    assert rig.failures == [], rig.failures


def test_not_set_is_refused_through_the_atomic_service_too(rig_factory):
    rig = rig_factory(armed_every_device())
    result = rig.call(SetParametersAtomically, f'{NODE}/set_parameters_atomically',
                      parameters=[ParameterMsg(name='ams.command_timeout')]).result
    assert not result.successful and 'ams.command_timeout cannot be unset' in result.reason
    assert rig.node.has_parameter('ams.command_timeout')


def test_a_parameter_of_no_known_type_is_answered_and_the_heartbeat_goes_on(rig_factory):
    rig = rig_factory(armed_every_device())
    odd = ParameterMsg(name='ams.bank_count', value=ParameterValue(type=NO_SUCH_TYPE))
    results = set_messages(rig, odd)
    assert len(results) == 1 and not results[0].successful
    assert 'refused' in results[0].reason, results[0].reason
    atomic = rig.call(SetParametersAtomically, f'{NODE}/set_parameters_atomically',
                      parameters=[odd]).result
    assert not atomic.successful
    mark = rig.capture.mark()
    rig.wait(lambda: len(rig.capture.since(mark, HEARTBEAT)) >= 3, what='3 more heartbeats')
    assert rig.node.commands_enabled
    assert rig.failures == [], rig.failures


def test_an_array_longer_than_its_maximum_is_refused_on_its_length_alone():
    spec = next(s for s in NODE_PARAMS if s.key == 'devices')
    assert spec.max_length == MAX_DEVICES
    from ams_can_bridge.devices.evms3.device import Evms3Device
    cells = next(s for s in Evms3Device.COMMAND_PARAMS if s.key == 'config.cells_per_module')
    assert cells.max_length == 16
    # every element is out of range too: the length is what is named, so no element was
    # looked at first
    with pytest.raises(ParamError, match=r'^evms3.config.cells_per_module has 17 values: '
                                         r'at most 16 are allowed$'):
        coerce(CELLS, cells, [99] * 17)
    options = ParamError
    with pytest.raises(options, match=f'at most {MAX_BUS_OPTIONS}'):
        from ams_can_bridge.parameters import BUS_PARAMS
        coerce('can.options', next(s for s in BUS_PARAMS if s.key == 'options'),
               ['x=1'] * (MAX_BUS_OPTIONS + 1))


def test_three_million_cell_counts_are_refused_and_a_disarm_after_them_is_answered(
        rig_factory):
    rig = rig_factory(armed_every_device())
    huge = Parameter(CELLS, value=array.array('q', [12]) * 3_000_000).to_parameter_msg()
    pending = rig.call_in_thread(SetParameters, f'{NODE}/set_parameters', parameters=[huge])
    disarm = rig.call(SetParameters, f'{NODE}/set_parameters', timeout=60.0, parameters=[
        Parameter('commands_enabled', value=False).to_parameter_msg()]).results[0]
    assert disarm.successful and not rig.node.commands_enabled
    pending['thread'].join(60.0)
    result = pending['response'].results[0]
    assert not result.successful
    assert result.reason == f'{CELLS} has 3000000 values: at most 16 are allowed'
    assert rig.node._parameters[CELLS].type_ == Parameter.Type.NOT_SET  # still unset
    frames_out = rig.frames_out()
    rig.assert_silent_since(frames_out)
    assert rig.failures == [], rig.failures


def test_a_bug_in_a_parameter_callback_is_answered_and_the_heartbeat_goes_on(
        rig_factory, monkeypatch):
    import ams_can_bridge.ros.bridge_node as bridge_node
    rig = rig_factory(armed_every_device())

    def broken(*args, **kwargs):
        raise RuntimeError('a bug')
    monkeypatch.setattr(rig.node.params, 'validate', broken)
    request = Parameter('ams.bank_count', value=3).to_parameter_msg()
    result = set_messages(rig, request)[0]
    assert not result.successful
    assert result.reason == 'internal error: RuntimeError: a bug', result.reason
    monkeypatch.undo()
    monkeypatch.setattr(bridge_node, 'apply_set', broken)  # after the set was accepted
    assert set_messages(rig, request)[0].successful
    mark = rig.capture.mark()
    rig.wait(lambda: len(rig.capture.since(mark, HEARTBEAT)) >= 3, what='3 more heartbeats')
    assert rig.failures == [], rig.failures
