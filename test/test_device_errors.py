"""Issue 21.7 in devices/: every deliberate raise is a package error, ValueError kept as base."""
import ast
import builtins
from pathlib import Path

import pytest

from ams_can_bridge import errors
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.ams import AmsDevice
from ams_can_bridge.devices.dbc_plan import MappingError
from ams_can_bridge.devices.ivt_s import IvtSDevice
from ams_can_bridge.devices.ivt_s_commands import NoAnswer

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


def test_devices_raise_no_built_in_exception():
    paths = sorted((PACKAGE / 'devices').glob('*.py')) + [PACKAGE / 'device_set.py']
    assert [r for p in paths for r in _builtin_raises(p)] == []


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
