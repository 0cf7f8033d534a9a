# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Array parameters set at run time through the real parameter service (issue 18, point 11).

``ros2 param set`` sends a SetParameters request; rclpy hands integer and float arrays to the
node's callbacks as ``array.array``, not as a list. Each array parameter that can be set at
run time is set here through ``/ams_can_bridge/set_parameters`` (not by calling the node's
method, which would hand it a list), with a valid value and with an invalid one.
"""
from __future__ import annotations

from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter

from shared import every_device

SERVICE = '/ams_can_bridge/set_parameters'
# A valid value of every writable array parameter (keyed by the parameter's key in its
# device); a new array parameter fails test_every_writable_array_parameter_is_covered until
# it has a value here.
VALID = {'config.cells_per_module': [12, 12, 10, 8] + [0] * 12}  # 16 modules
INVALID = {'config.cells_per_module': ([12, 99], 'cells_per_module[1] = 99 is out of range')}


def writable_arrays(node) -> dict[str, str]:
    """Return {parameter name: key} of every declared array parameter settable at run time."""
    return {name: name.split('.', 1)[1] if '.' in name else name
            for name, spec in node.params.specs.items()
            if isinstance(spec.type, str) and spec.type.endswith('[]') and not spec.read_only}


def set_through_service(rig, name, value):
    request = [Parameter(name, value=value).to_parameter_msg()]
    return rig.call(SetParameters, SERVICE, parameters=request).results[0]


def test_every_writable_array_parameter_is_covered(rig_factory):
    rig = rig_factory(every_device())
    keys = set(writable_arrays(rig.node).values())
    assert keys, 'no writable array parameter found: the test would prove nothing'
    assert keys <= set(VALID), f'add a valid value to VALID for {sorted(keys - set(VALID))}'


def test_array_parameters_set_through_the_parameter_service(rig_factory):
    rig = rig_factory(every_device())
    arrays = writable_arrays(rig.node)
    assert arrays
    for name, key in arrays.items():
        result = set_through_service(rig, name, VALID[key])
        assert result.successful, f'{name}: {result.reason}'
        assert list(rig.node.get_parameter(name).value) == VALID[key]
        device = rig.node.devices[name.partition('.')[0]]
        assert list(device.config.value(key)) == VALID[key], 'the device did not get it'


def test_invalid_array_value_is_refused_naming_the_element(rig_factory):
    rig = rig_factory(every_device())
    for name, key in writable_arrays(rig.node).items():
        value, reason = INVALID[key]
        result = set_through_service(rig, name, value)
        assert not result.successful
        assert reason in result.reason and 'must be a list' not in result.reason
