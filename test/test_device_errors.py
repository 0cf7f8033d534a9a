# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Every deliberate raise of the package is a package error, ValueError kept as its base."""
import ast
import builtins
from pathlib import Path

import pytest

from ams_can_bridge import errors, registry
from ams_can_bridge.can_io import BusConfig, parse_options, ReplayBus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.protocols.dbc_mapping.plan import MappingError
from ams_can_bridge.devices.ivt_s.device import IvtSDevice
from ams_can_bridge.devices.ivt_s.exchanges import NoAnswer
from ams_can_bridge.sim.main import apply_faults

PACKAGE = Path(__file__).resolve().parent.parent / 'ams_can_bridge'
# An abstract method's marker is no error a user meets.
ALLOWED_BUILTINS = {'NotImplementedError'}


def _builtin_raises(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Raise) and node.exc is not None:
            exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            name = exc.id if isinstance(exc, ast.Name) else None
            if (name in dir(builtins) and name not in ALLOWED_BUILTINS
                    and isinstance(getattr(builtins, name), type)):
                found.append(f'{path.name}:{node.lineno} raise {name}')
    return found


def test_the_package_raises_no_built_in_exception():
    paths = sorted(PACKAGE.rglob('*.py'))
    assert len(paths) > 30 and PACKAGE / 'devices' / 'base.py' in paths
    assert [r for p in paths for r in _builtin_raises(p)] == []


def test_the_scan_sees_a_built_in_raise(tmp_path):
    source = tmp_path / 'x.py'
    source.write_text('def f(x):\n    if x:\n        raise ValueError(x)\n'
                      '    raise KeyError\n    raise NotImplementedError\n')
    assert sorted(_builtin_raises(source)) == ['x.py:3 raise ValueError', 'x.py:4 raise KeyError']


def test_bus_sim_and_registry_errors_are_config_errors_and_still_value_errors(tmp_path):
    with pytest.raises(errors.ConfigError, match='can.bitrate = -1'):
        BusConfig(interface='virtual', bitrate=-1)
    with pytest.raises(ValueError, match='is not a valid option name'):
        parse_options(['1x=2'])
    with pytest.raises(errors.ConfigError, match='unknown device type'):
        registry.device_class('no_such_bms')
    with pytest.raises(errors.ConfigError, match='no simulated device'):
        apply_faults([], [('ams', 'silent', True)])
    with pytest.raises(errors.LogFileError, match='does not exist'):
        ReplayBus(str(tmp_path / 'missing.log'))


def test_device_errors_are_package_errors_and_still_value_errors():
    assert issubclass(MappingError, errors.ConfigError) and issubclass(MappingError, ValueError)
    assert issubclass(NoAnswer, errors.AmsCanBridgeError)
    with pytest.raises(errors.ParamError, match='ams.bank_count = 9'):
        AmsDevice('ams', {'bank_count': 9})
    with pytest.raises(errors.ParamError, match='unknown parameter'):
        IvtSDevice('shunt', {}).configure({'no_such_key': 1})
    with pytest.raises(errors.ParamError, match='discharge_positive'):
        IvtSDevice('shunt', {'discharge_positive': 'sideways'})
    with pytest.raises(ValueError):  # callers that catch ValueError keep working
        AmsDevice('ams', {}).configure({'bank_count': 6})


def test_device_set_lets_a_programming_error_through():
    """A TypeError inside a device's set-up is a bug: not dressed up as a ConfigError."""
    values = {'ams.stale_timeout': [0.5]}  # cannot come from declare (parameters.coerce)
    with pytest.raises(TypeError):
        DeviceSet(['ams'], lambda name, spec: values.get(name, spec.default))
