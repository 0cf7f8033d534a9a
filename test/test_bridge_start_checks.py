# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The most common set-up mistakes are refused at start, naming what to change (issue 18).

Each test makes the mistake as a new user would and checks the answer: the exit code, the
message naming the key and what to write instead, and that nothing reached the adapter (the
bridge stops before opening the bus). Points: 1 unknown keys, a params file for another node,
no devices; 2 overlapping device IDs; 5 settings that can never work; 9 --help, simulator
--fault.
"""
from __future__ import annotations

import itertools
import os
import subprocess
import sys
import threading

import pytest
from rclpy.parameter import Parameter

from ams_can_bridge.can_io.config import BusConfig, parse_options
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.offline.converter import Converter
from ams_can_bridge.offline.params_file import load_parameters, section_applies
from ams_can_bridge.parameters import coerce
from ams_can_bridge.ros.bridge_node import BridgeNode
from ams_can_bridge.ros.params import unmatched_params_files
from ams_can_bridge.sim import main as sim_main
from bridge_runs import assert_nothing_reached, node_error, run_bridge, slcan_yaml
from executables import bridge_executable
from helpers import ros_context
from slcan_peer import SlcanPeer

_ids = itertools.count()
TYPOS = ('/**:\n  ros__parameters:\n    device: [ams]\n    devices: [ams, ivt_s]\n'
         '    commands_alowed: true\n    ams: {bank_cont: 5}\n')
TYPO_MESSAGES = [
    '4 parameters need a change',
    'ams.bank_cont: unknown parameter of device ams (type ams); did you mean `ams.bank_count`?',
    'commands_alowed: unknown parameter (the bridge does not declare it); did you mean '
    '`commands_allowed`?',
    'device: unknown parameter (the bridge does not declare it); did you mean `devices`?',
    'ivt_s.discharge_positiv: unknown parameter of device ivt_s (type ivt_s); did you mean '
    '`ivt_s.discharge_positive`?',
]


@pytest.fixture
def context():
    with ros_context() as ctx:
        yield ctx


# --- 1: unknown keys ----------------------------------------------------------------------
def test_unknown_keys_stop_the_bridge_naming_each_and_the_nearest_name(tmp_path):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_typos')
    try:
        proc = run_bridge(tmp_path, slcan_yaml(peer, TYPOS + '    commands_enabled: false\n'),
                          '-p', 'ivt_s.discharge_positiv:=false')
        assert proc.returncode == 2, proc.stderr
        assert 'Traceback' not in proc.stderr
        for message in TYPO_MESSAGES:
            assert message in proc.stderr, (message, proc.stderr)
        assert_nothing_reached(peer)
    finally:
        peer.shutdown()


@pytest.mark.parametrize('overrides, expected', [
    ({'devices': ['ivt_s'], 'ams.bank_count': 1},
     "ams.bank_count: belongs to no configured device: 'ams' is not in devices (devices "
     'lists ivt_s); add ams to devices (with ams.type: ams) or remove the key'),
    ({'devices': ['ams'], 'ams.type': 'ivt_s', 'ams.bank_count': 1},
     'ams.bank_count: unknown parameter of device ams (type ivt_s) (bank_count is a '
     'parameter of type ams)'),
    ({'devices': ['pack', 'shunt'], 'pack.type': 'ams', 'shunt.type': 'ivt_s',
      'ams.bank_count': 1},
     "ams.bank_count: belongs to no configured device: 'ams' is not in devices (devices "
     'lists pack, shunt); add ams to devices (with ams.type: ams) or remove the key; did '
     'you mean `pack.bank_count`?'),
    ({'can.interfce': 'virtual'},
     'can.interfce: unknown parameter (the bridge does not declare it); did you mean '
     '`can.interface`?'),
])
def test_a_device_key_says_whose_it_is(context, overrides, expected):
    assert expected in node_error(context, overrides)


def test_every_problem_of_the_start_values_is_listed_at_once(context):
    text = node_error(context, {
        'can.interface': 'slcn', 'devices': ['ams', 'ams2'], 'ams2.type': 'ams',
        'ams.bank_count': 9, 'ams.bank_cont': 5, 'diagnostics_perod': 1.0})
    assert text.startswith('5 parameters need a change:')
    for message in ("can.interface = 'slcn' is not a python-can interface",
                    'ams.bank_count = 9 is out of range: allowed 1..5',
                    'ams.bank_cont: unknown parameter of device ams (type ams); did you mean '
                    '`ams.bank_count`?',
                    'diagnostics_perod: unknown parameter',
                    'devices overlap: ams (ams) and ams2 (ams) both use IDs 0x300-0x301'):
        assert message in text, (message, text)


def test_known_keys_of_rclpy_itself_are_not_refused(context):
    node = BridgeNode(context=context, namespace=f'checks_{next(_ids)}', parameter_overrides=[
        Parameter('can.interface', value='virtual'), Parameter('can.channel', value='rclpy'),
        Parameter('use_sim_time', value=False),
        Parameter('qos_overrides./diagnostics.publisher.depth', value=10)])
    node.destroy_node()


def test_log2bag_refuses_the_same_keys_in_the_same_words(tmp_path, context):
    params = tmp_path / 'typos.yaml'
    params.write_text(TYPOS + '    ivt_s: {discharge_positiv: false}\n')
    with pytest.raises(ParamError) as offline:
        Converter(load_parameters(str(params), 'ams_can_bridge'), None, 'replay:x')
    values = load_parameters(str(params), 'ams_can_bridge')
    live = node_error(context, values)
    for message in TYPO_MESSAGES:
        assert message in str(offline.value) and message in live, message
    assert str(offline.value).splitlines() == live.splitlines()


def test_params_file_for_another_node_warns_and_names_its_sections(tmp_path):
    params = tmp_path / 'named.yaml'
    params.write_text('ams_can_bridge:\n  ros__parameters:\n    devices: [ams]\n')
    proc = subprocess.Popen(
        [bridge_executable(), '--ros-args', '-r', '__ns:=/car2', '--params-file', str(params),
         '-p', 'can.interface:=virtual', '-p', f'can.channel:=car2-{os.getpid()}',
         '-p', 'can.options:=[recieve_own_messages=true]'],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=dict(os.environ))
    lines: list[str] = []
    watchdog = threading.Timer(30.0, proc.kill)  # bounds the read below: EOF at the latest
    watchdog.start()
    try:
        for line in proc.stdout:
            lines.append(line)
            if 'recieve_own_messages' in line:
                break
    finally:
        watchdog.cancel()
        proc.terminate()
        rest, _ = proc.communicate(timeout=20)
    output = ''.join(lines) + rest
    assert (f'params file {params}: no section applies to this node /car2/ams_can_bridge '
            '(its sections: ams_can_bridge), so none of its values is used. Key it '
            '/car2/ams_can_bridge: or /**:') in output, output
    assert 'devices is empty: the bridge decodes nothing' in output
    assert "Set devices to your instances in the params file (e.g. devices: [ams, ivt_s]" \
        in output
    assert ("can.options recieve_own_messages: not an argument of python-can's VirtualBus "
            '(interface virtual; it names ') in output
    assert 'did you mean recieve_own_messages -> receive_own_messages?' in output
    assert proc.returncode == 0, output


def test_section_matching_follows_rcl():
    assert section_applies('/**', '/car2/ams_can_bridge')
    assert section_applies('**', '/ams_can_bridge')
    assert section_applies('/*/ams_can_bridge', '/car2/ams_can_bridge')
    assert section_applies('car2/ams_can_bridge', '/car2/ams_can_bridge')
    assert not section_applies('ams_can_bridge', '/car2/ams_can_bridge')
    assert not section_applies('/*', '/car2/ams_can_bridge')


def test_matching_file_gives_no_section_warning(tmp_path):
    params = tmp_path / 'ok.yaml'
    params.write_text('/car2/ams_can_bridge:\n  ros__parameters:\n    devices: []\n')
    argv = ['bridge', '--ros-args', '--params-file', str(params)]
    assert unmatched_params_files(argv, '/car2/ams_can_bridge') == []
    assert len(unmatched_params_files(argv, '/car3/ams_can_bridge')) == 1


# --- 2: overlapping IDs -------------------------------------------------------------------
def test_overlapping_instances_stop_the_bridge_and_nothing_is_sent(tmp_path):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_twins')
    try:
        proc = run_bridge(tmp_path, slcan_yaml(peer, (
            '/**:\n  ros__parameters:\n    devices: [ams, ams2]\n    ams2: {type: ams}\n'
            '    commands_allowed: true\n    commands_enabled: true\n')))
        assert proc.returncode == 2, proc.stderr
        assert 'Traceback' not in proc.stderr
        assert ('devices overlap: ams (ams) and ams2 (ams) both use IDs 0x300-0x301, 0x305, '
                '0x310-0x314') in proc.stderr, proc.stderr
        assert 'Move one of them (<name>.base_id) or remove it from devices' in proc.stderr
        assert_nothing_reached(peer)  # no heartbeat, not even the channel opened
    finally:
        peer.shutdown()


def device_set(names, values):
    def declare(name, spec):
        value = values.get(name, spec.default)
        return None if value is None else coerce(name, spec, value)
    return DeviceSet(names, declare)


def test_every_overlapping_pair_is_named_with_its_ids():
    with pytest.raises(ConfigError) as info:
        device_set(['evms3', 'bms16', 'b2', 'z2'],
                   {'b2.type': 'bms16', 'b2.base_id': 502, 'z2.type': 'evms3',
                    'z2.base_id': 31})
    text = str(info.value)
    assert ('bms16 (bms16) and b2 (bms16) both use IDs 0x1F6-0x1F7, 0x351, 0x355-0x356, '
            '0x35A, 0x35E-0x35F') in text
    assert 'evms3 (evms3) and z2 (evms3) both use IDs 0x1F-0x29' in text


def test_the_sma_frames_of_a_bms16_may_be_read_by_an_sma_instance_too():
    # The BMS16 sends the SMA frames (fixed IDs, one sender per bus); the sma instance
    # shows the same pack through the SMA protocol, as the demo does.
    devices = device_set(['ams', 'ivt_s', 'evms3', 'bms16', 'sma'], {})
    assert devices.handle_targets(0x351, False) == (devices.devices['bms16'],
                                                    devices.devices['sma'])
    with pytest.raises(ConfigError, match=r'sma \(sma\) and sma2 \(sma\) both use IDs 0x351'):
        device_set(['sma', 'sma2'], {'sma2.type': 'sma'})


# --- 5: settings that can never work ------------------------------------------------------
def test_unknown_interface_stops_the_bridge(tmp_path):
    proc = run_bridge(tmp_path, '/**:\n  ros__parameters:\n    devices: [bms16]\n'
                      '    can: {interface: slcn, channel: /dev/ttyACM0}\n')
    assert proc.returncode == 2 and 'Traceback' not in proc.stderr
    assert ("can.interface = 'slcn' is not a python-can interface; did you mean 'slcan'? "
            '(known: ') in proc.stderr, proc.stderr


def test_slcan_bitrate_the_adapter_cannot_do_stops_the_bridge(tmp_path):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_rate')
    try:
        proc = run_bridge(tmp_path, slcan_yaml(
            peer, '/**:\n  ros__parameters:\n    devices: [bms16]\n', bitrate=300000))
        assert proc.returncode == 2, proc.stderr
        assert ('can.bitrate = 300000: an slcan adapter has no command for it; use one of '
                '10000, 20000, 50000, 83300, 100000, 125000, 250000, 500000, 750000, 1000000 '
                '(or 0 = leave it as is)') in proc.stderr, proc.stderr
        assert_nothing_reached(peer)
    finally:
        peer.shutdown()


def test_an_absent_adapter_is_not_a_configuration_error():
    # the channel may be plugged in later: check() leaves it to the retrying receive thread
    assert BusConfig(interface='slcan', channel='/dev/nonexistent_adapter',
                     bitrate=500000).check() == []


def test_replay_of_a_missing_file_stops_at_start():
    with pytest.raises(ValueError, match="can.channel = '/nonexistent.log': the log file to "
                                         'replay does not exist'):
        BusConfig(interface='replay', channel='/nonexistent.log').check()


class StrictBus:
    """An interface class that takes no **kwargs: python-can raises TypeError on an option."""

    def __init__(self, channel, bitrate=None, can_filters=None):
        pass


def test_option_an_interface_cannot_take_stops_at_start(monkeypatch):
    import can.interface
    import can.interfaces
    monkeypatch.setattr(can.interfaces, 'VALID_INTERFACES',
                        can.interfaces.VALID_INTERFACES | {'strict'})
    monkeypatch.setattr(can.interface, '_get_class_for_interface', lambda name: StrictBus)
    config = BusConfig(interface='strict', options=parse_options(['bitrat=5', 'fd=true']))
    with pytest.raises(ValueError) as info:
        config.check()
    assert str(info.value) == ("can.options bitrat: not an argument of python-can's StrictBus "
                               '(interface strict; it names bitrate, can_filters); did you '
                               'mean bitrat -> bitrate?')


# --- 9: --help and simulator --fault ------------------------------------------------------
def test_help_prints_usage_and_exits_0_without_starting_ros():
    # an RMW that does not exist: had ROS been started, the bridge would fail
    env = dict(os.environ, RMW_IMPLEMENTATION='rmw_that_does_not_exist')
    for flag in ('--help', '-h'):
        proc = subprocess.run([bridge_executable(), flag], capture_output=True, text=True,
                              timeout=60, env=env)
        assert proc.returncode == 0, proc.stderr
        assert proc.stderr == ''
        for words in ('usage: bridge', '--ros-args --params-file PARAMS.yaml',
                      '-p NAME:=VALUE', 'can.interface', 'can.channel', 'devices',
                      'commands_allowed', 'doc/parameters.md', 'doc/topics_services.md',
                      'doc/failure_modes.md', 'doc/real_bus.md',
                      'config/*.yaml', 'ams-can-bridge'):
            assert words in proc.stdout, words


def test_an_argument_outside_ros_args_is_refused():
    proc = subprocess.run([bridge_executable(), '--params-file', 'my.yaml'],
                          capture_output=True, text=True, timeout=60, env=dict(os.environ))
    assert proc.returncode == 2
    assert proc.stderr.startswith('bridge: unknown argument(s) --params-file my.yaml: '
                                  'parameters go after --ros-args')


def test_simulator_refuses_an_unknown_fault_listing_the_valid_ones(capsys):
    assert sim_main.main(['--devices', 'ams', '--fault', 'ams:stuck', '--duration', '0']) == 2
    assert capsys.readouterr().err == (
        'simulator: --fault ams:stuck: no such fault of ams; use one of cell_drift_v, drift, '
        'drift_cell, error, error_code, imd_error, malformed, silent, stuck_counter\n')
    assert sim_main.main(['--devices', 'ams', '--fault', 'ams:stuck_counter', '--duration',
                          '0', '--quiet']) == 0


if __name__ == '__main__':
    sys.exit(pytest.main([__file__]))
