"""Every config/*.yaml loads unchanged into the bridge node, with the values it declares."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from rclpy.exceptions import ParameterUninitializedException
import yaml

from ams_can_bridge import registry
from ams_can_bridge.ros.bridge_node import BridgeNode
from helpers import ros_context

CONFIG = Path(__file__).resolve().parents[1] / 'config'
FILES = sorted(CONFIG.glob('*.yaml'))


@pytest.fixture(scope='module')
def context():
    with ros_context() as ctx:
        yield ctx


def flatten(tree: dict[str, Any], prefix: str = '') -> dict[str, Any]:
    out = {}
    for key, value in tree.items():
        if isinstance(value, dict):
            out.update(flatten(value, f'{prefix}{key}.'))
        else:
            out[prefix + key] = value
    return out


def test_config_files_exist():
    names = {p.name for p in FILES}
    assert {'ams_ivt.yaml', 'evms3.yaml', 'bms16.yaml', 'sma.yaml'} <= names


@pytest.mark.parametrize('path', FILES, ids=lambda p: p.name)
def test_config_file_loads_in_the_node(context, path):
    expected = flatten(yaml.safe_load(path.read_text())['/**']['ros__parameters'])
    node = BridgeNode(context=context, namespace=f'cfg_{path.stem}',
                      cli_args=['--ros-args', '--params-file', str(path)])
    try:
        for name, value in expected.items():
            assert node.has_parameter(name), f'{path.name}: {name} is not a bridge parameter'
            if value == []:
                # YAML [] carries no element type: rclpy leaves the array unset (= empty)
                try:
                    declared = node.get_parameter(name).value
                except ParameterUninitializedException:
                    declared = None
                assert declared in (None, []), name
                continue
            declared = node.get_parameter(name).value
            if isinstance(value, float) or isinstance(declared, float):
                assert declared == pytest.approx(value), name
            else:
                assert declared == value, name
        assert node.devices, f'{path.name} configures no device'
        for name, device in node.devices.items():
            assert device.TYPE in registry.DEVICE_TYPES
            assert device.TYPE == expected.get(f'{name}.type', name)
        assert node.commands_enabled is False  # examples never transmit out of the box
    finally:
        node.destroy_node()


@pytest.mark.parametrize('name', ['evms3', 'bms16'])
def test_zeva_examples_hold_a_complete_configuration(context, name):
    """The example sets every config value, so write_config would not refuse it."""
    path = CONFIG / f'{name}.yaml'
    in_file = {key for key in flatten(yaml.safe_load(path.read_text())['/**']['ros__parameters'])
               if key.startswith(f'{name}.config.')}
    node = BridgeNode(context=context, namespace=f'cfg_full_{name}',
                      cli_args=['--ros-args', '--params-file', str(path)])
    try:
        declared = {key for key in node._parameters if key.startswith(f'{name}.config.')}
        assert declared and in_file == declared, declared ^ in_file
    finally:
        node.destroy_node()
