# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Start-up attacks (issue 26, points 5, 8, 12, 13, 14): exit 2 with the reason, or a WARN.

Each stops the bridge with exit 2 and one clear reason before anything reaches the
adapter, or (14) warns at start. 5: an ID one instance sends (the SMA keep-alive 0x305)
that another sends or reads (the AMS heartbeat 0x305); 8: a key given twice in a params
file, or a second section for the node (the bridge and log2bag); 12: ten thousand
overlapping devices; 13: instance names that are no ROS names; 14: commands_allowed without
SROS2.
"""
from __future__ import annotations

import os

import pytest
from rclpy.parameter import Parameter

from ams_can_bridge.device_set import DeviceSet, overlap_problems
from ams_can_bridge.engine.startup import security_warning
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.offline.log2bag import main as log2bag
from ams_can_bridge.offline.params_file import load_parameters
from ams_can_bridge.parameters import coerce, MAX_DEVICES
from bridge_runs import node_error, stopped_before_the_adapter
from helpers import ros_context

ARMED = '    commands_allowed: true\n    commands_enabled: true\n'
KEEPALIVE_ID = 0x305


@pytest.fixture
def context():
    with ros_context() as ctx:
        yield ctx


def device_set(names, values):
    def declare(name, spec):
        value = values.get(name, spec.default)
        return None if value is None else coerce(name, spec, value)
    return DeviceSet(names, declare)


# --- 5: IDs a device sends ----------------------------------------------------------------
def test_the_sma_keepalive_on_the_ams_heartbeat_id_stops_the_bridge(tmp_path):
    err = stopped_before_the_adapter(tmp_path, (
        '/**:\n  ros__parameters:\n    devices: [ams, sma]\n'
        '    sma: {inverter_keepalive: true}\n' + ARMED), 'keepalive')
    assert ('devices overlap: ams (ams) and sma (sma) both send ID 0x305 (ams: car status '
            'heartbeat; sma: inverter keep-alive)') in err, err
    assert 'turn the keep-alive off (<name>.inverter_keepalive: false)' in err


def test_a_keepalive_on_an_id_another_instance_reads_is_named():
    with pytest.raises(ConfigError) as info:
        device_set(['sma', 'shunt'], {'sma.inverter_keepalive': True, 'shunt.type': 'ivt_s',
                                      'shunt.base_id': KEEPALIVE_ID})
    assert ('sma (sma) sends its inverter keep-alive on ID 0x305, which shunt (ivt_s) reads'
            in str(info.value))
    device_set(['ams', 'sma'], {})  # the keep-alive off (its default): nothing shared


def test_the_keepalive_switched_on_at_run_time_over_the_heartbeat_is_refused(rig_factory):
    rig = rig_factory({'devices': ['ams', 'sma'], 'commands_allowed': True,
                       'commands_enabled': True})
    result = rig.set_param('sma.inverter_keepalive', True)
    assert not result.successful
    assert 'ams (ams) and sma (sma) both send ID 0x305' in result.reason, result.reason
    assert not rig.node.devices['sma'].config.inverter_keepalive
    assert not rig.node.devices['sma'].keepalive.running


# --- 8: a key given twice, a second section ---------------------------------------------
DUPLICATE = ('/**:\n  ros__parameters:\n    devices: [ams]\n    commands_allowed: false\n'
             '    commands_enabled: true\n    ams: {bank_count: 5}\n    commands_allowed: true\n')


def test_a_key_given_twice_stops_the_bridge_naming_the_key_and_both_lines(tmp_path):
    err = stopped_before_the_adapter(tmp_path, DUPLICATE, 'twice')
    assert ('/**: ros__parameters: commands_allowed is given twice, line 4 (false) and line 7 '
            '(true)') in err, err
    assert 'commands ENABLED' not in err and 'heartbeat started' not in err


def test_a_second_section_for_the_node_stops_the_bridge(tmp_path):
    err = stopped_before_the_adapter(tmp_path, (
        'ams_can_bridge:\n  ros__parameters:\n    devices: [ams]\n    commands_allowed: false\n'
        '/ams_can_bridge:\n  ros__parameters:\n    commands_allowed: true\n'
        '    commands_enabled: true\n'), 'sections')
    assert ("a second section for the node 'ams_can_bridge': line 1 (ams_can_bridge:) and "
            'line 5 (/ams_can_bridge:): merge them into one section') in err, err


def test_a_key_given_with_dots_and_nested_is_given_twice(tmp_path):
    params = tmp_path / 'dots.yaml'
    params.write_text('/**:\n  ros__parameters:\n    ams:\n      bank_count: 1\n'
                      '    ams.bank_count: 5\n')
    with pytest.raises(ConfigError, match=r'ams.bank_count is given twice, line 4 \(1\) and '
                                          r'line 5 \(5\)'):
        load_parameters(str(params), 'ams_can_bridge')


def test_log2bag_refuses_a_key_given_twice(tmp_path, capsys):
    params = tmp_path / 'twice.yaml'
    params.write_text(DUPLICATE)
    log = tmp_path / 'empty.log'
    log.write_text('(0.000000) vcan0 123#00\n')
    assert log2bag([str(log), str(tmp_path / 'bag'), '--params-file', str(params)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('log2bag: ') and 'Traceback' not in err
    assert 'commands_allowed is given twice, line 4 (false) and line 7 (true)' in err, err
    assert not (tmp_path / 'bag').exists()


# --- 12: ten thousand devices -------------------------------------------------------------
def test_ten_thousand_overlapping_devices_stop_the_bridge_at_once_saying_why(tmp_path):
    names = [f'a{i}' for i in range(10_000)]
    body = ('/**:\n  ros__parameters:\n    devices: [' + ', '.join(names) + ']\n'
            + ''.join(f'    {name}: {{type: ams}}\n' for name in names))
    err = stopped_before_the_adapter(tmp_path, body, 'many')
    assert f'devices has 10000 values: at most {MAX_DEVICES} are allowed' in err, err[-3000:]
    assert len(err) < 20_000, 'the reason is buried in the output'


def test_the_device_cap_holds_for_a_device_set_built_directly():
    with pytest.raises(ConfigError, match=f'devices has {MAX_DEVICES + 1} instances: at most '
                                          f'{MAX_DEVICES}'):
        device_set([f'a{i}' for i in range(MAX_DEVICES + 1)], {})


def test_every_pair_of_the_most_overlapping_devices_is_named_once():
    names = [f'a{i}' for i in range(MAX_DEVICES)]
    with pytest.raises(ConfigError) as info:
        device_set(names, {f'{n}.type': 'ams' for n in names})
    text = str(info.value)
    pairs = MAX_DEVICES * (MAX_DEVICES - 1) // 2
    assert text.count(' both use IDs 0x300-0x301, 0x305, 0x310-0x314;') == pairs
    assert text.count(' both send IDs 0x350-0x351 ') == pairs
    # instances apart: nothing to name
    spread = device_set(names[:20], {**{f'{n}.type': 'ams' for n in names[:20]},
                                     **{f'{n}.base_id': 0x60 * i
                                        for i, n in enumerate(names[:20])}})
    assert overlap_problems(spread.devices) == []


# --- 13: names that are no ROS names ------------------------------------------------------
@pytest.mark.parametrize('name', ['my-ams', '9ams', 'pack one', 'ams/1'])
def test_an_instance_name_that_is_no_ros_name_names_the_rule(context, name):
    text = node_error(context, {'devices': [name], f'{name}.type': 'ams'})
    assert f'devices: {name!r} is not a usable instance name' in text, text
    assert ('must be a ROS name: letters, digits and underscores, not starting with a digit'
            in text)


def test_a_dashed_instance_name_is_exit_2_without_a_traceback(tmp_path):
    err = stopped_before_the_adapter(tmp_path, (
        '/**:\n  ros__parameters:\n    devices: [my-ams]\n    my-ams: {type: ams}\n'), 'dash')
    assert "devices: 'my-ams' is not a usable instance name" in err, err
    assert "(e.g. 'my_ams')" in err


# --- 14: commands_allowed without SROS2 ---------------------------------------------------
def test_commands_allowed_without_sros2_warns_at_start(context, monkeypatch, capfd):
    from ams_can_bridge.ros.bridge_node import BridgeNode
    for name in ('ROS_SECURITY_ENABLE', 'ROS_SECURITY_STRATEGY'):
        monkeypatch.delenv(name, raising=False)
    node = BridgeNode(context=context, namespace='open_check', parameter_overrides=[
        Parameter('can.interface', value='virtual'),
        Parameter('can.channel', value=f'open-{os.getpid()}'),
        Parameter('commands_allowed', value=True)])
    try:
        assert node.commands_allowed and not node.commands_enabled  # started all the same
    finally:
        node.destroy_node()
    lines = capfd.readouterr().err.splitlines()
    warning = [line for line in lines if 'security is not enforced' in line]
    assert len(warning) == 1 and warning[0].startswith('[WARN]'), lines
    assert ('commands_allowed is true and ROS 2 security is not enforced (ROS_SECURITY_ENABLE='
            f'unset, ROS_SECURITY_STRATEGY=unset): any node on ROS_DOMAIN_ID '
            f'{os.environ["ROS_DOMAIN_ID"]} can set commands_enabled and command the bridge'
            ) in warning[0]


def test_the_sros2_warning_only_without_enforced_security():
    assert security_warning(False, {}) is None
    enforced = {'ROS_SECURITY_ENABLE': 'true', 'ROS_SECURITY_STRATEGY': 'Enforce'}
    assert security_warning(True, enforced) is None
    permissive = security_warning(True, {**enforced, 'ROS_SECURITY_STRATEGY': 'Permissive'})
    assert permissive and 'ROS_SECURITY_STRATEGY=Permissive' in permissive
    assert 'ROS_DOMAIN_ID 7' in security_warning(True, {'ROS_DOMAIN_ID': '7'})
