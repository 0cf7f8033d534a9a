# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
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
# The bridge's parameter files (diagnostics_aggregator.yaml configures another node; a
# *_mapping.yaml is a dbc device's mapping file, doc/own_bms.md).
FILES = sorted(p for p in CONFIG.glob('*.yaml') if p.name != 'diagnostics_aggregator.yaml'
               and not p.name.endswith('_mapping.yaml'))


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


@pytest.mark.parametrize('path', FILES, ids=lambda p: p.name)
def test_config_file_loads_in_log2bag(path, tmp_path):
    """log2bag reads the same files without ROS, with the same values and checks."""
    from ams_can_bridge.offline.converter import Converter
    from ams_can_bridge.offline.params_file import load_parameters
    converter = Converter(load_parameters(str(path), 'ams_can_bridge'), None, 'replay:x')
    expected = flatten(yaml.safe_load(path.read_text())['/**']['ros__parameters'])
    assert list(converter.devices.devices) == expected['devices']


def bridge_status_names() -> set[str]:
    names = {'ams_can_bridge: CAN bus'}
    for path in FILES:
        devices = yaml.safe_load(path.read_text())['/**']['ros__parameters']['devices']
        names |= {f'ams_can_bridge: {name}' for name in devices}
    return names


def test_diagnostics_aggregator_groups_every_status_of_the_examples():
    analyzers = yaml.safe_load((CONFIG / 'diagnostics_aggregator.yaml').read_text())
    groups = analyzers['analyzers']['ros__parameters']
    assert isinstance(groups.pop('path'), str)
    matched = {}
    for key, group in groups.items():
        assert group['type'] == 'diagnostic_aggregator/GenericAnalyzer' and group['path'], key
        for name in bridge_status_names():
            if name in group.get('expected', []) or any(
                    name.startswith(prefix) for prefix in group.get('startswith', [])):
                matched.setdefault(name, []).append(key)
    assert set(matched) == bridge_status_names()
    assert all(len(keys) == 1 for keys in matched.values()), matched


def published_topics() -> dict[str, set[str]]:
    """Every topic a shipped config's bridge publishes per device -> the fields it carries."""
    from sensor_msgs.msg import BatteryState
    from std_msgs.msg import Float32
    battery = set(BatteryState.get_fields_and_field_types())
    figure = set(Float32.get_fields_and_field_types())
    topics: dict[str, set[str]] = {}
    for path in FILES:
        params = flatten(yaml.safe_load(path.read_text())['/**']['ros__parameters'])
        for name in params['devices']:
            cls = registry.device_class(params.get(f'{name}.type', name),
                                        params.get(f'{name}.variant'))
            topics.setdefault(f'/{name}/battery_state', set()).update(battery)
            for suffix in cls.FIGURES:  # a pack's limits and time-to-go
                topics.setdefault(f'/{name}/{suffix}', set()).update(figure)
    return topics


def test_foxglove_layout_uses_the_bridges_topics_and_fields():
    import json

    layout = json.loads((CONFIG / 'foxglove_layout.json').read_text())
    paths = [p['value'] for panel in layout['configById'].values()
             for p in panel.get('paths', [])]
    assert paths
    published = published_topics()
    for path in paths:
        topic, _, field = path.partition('.')
        assert topic in published, f'{path}: no shipped config publishes {topic}'
        assert field.split('[')[0] in published[topic], path
    # the pack's limits and time-to-go (config/pack.yaml) are in it, as doc/visualization.md says
    assert {'/pack/charge_current_limit.data', '/pack/discharge_current_limit.data',
            '/pack/time_to_empty.data', '/pack/time_to_full.data'} <= set(paths)
    rendered = {panel.get('topicToRender') for panel in layout['configById'].values()}
    assert '/diagnostics' in rendered

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node['first']) + leaves(
            node['second'])
    assert sorted(leaves(layout['layout'])) == sorted(layout['configById'])
