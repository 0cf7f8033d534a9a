# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Files a user hands the package (issue 34, points 4, 5, 10).

5: every YAML the package reads (params files, mapping files, a probe's params file read
back) refuses an alias bomb, naming the file, before it expands; a params file takes no
alias at all, as rcl. 10: a FIFO, ``/dev/zero`` or a directory given as a log, a replay file,
a DBC, a mapping or a params file is "not a regular file", not "does not exist". 4: a key
given in two sections that both apply to the node (``/**`` and ``ams_can_bridge``, ...) is
refused naming both sections, whatever their spelling.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import subprocess

import pytest

from ams_can_bridge.can_io.config import BusConfig
from ams_can_bridge.can_io.replay import ReplayBus
from ams_can_bridge.protocols.dbc_mapping.mapping import load_plan
from ams_can_bridge.protocols.dbc_mapping.plan import MappingError
from ams_can_bridge.protocols.dbc_profiles import profile_files
from ams_can_bridge.errors import ConfigError, LogFileError
from ams_can_bridge.input_files import ALIAS_VALUES_LIMIT, file_problem, load_yaml
from ams_can_bridge.offline.log2bag import main as log2bag
from ams_can_bridge.offline.params_file import duplicate_problems, load_parameters
from ams_can_bridge.ros.params import node_name_from_argv
from bridge_runs import assert_nothing_reached, run_bridge, slcan_yaml, stopped_before_the_adapter
from executables import bridge_executable
from shared import one_line_error
from slcan_peer import SlcanPeer

NODE = 'ams_can_bridge'


def alias_bomb(levels: int = 6, width: int = 10) -> str:
    """Return a billion-laughs document: width ** levels values from a few hundred bytes."""
    lines = ['l0: &l0 [' + ', '.join(['lol'] * width) + ']']
    for level in range(1, levels):
        lines.append(f'l{level}: &l{level} [' + ', '.join([f'*l{level - 1}'] * width) + ']')
    return '\n'.join(lines) + '\n'


@pytest.fixture
def special_paths(tmp_path: Path) -> dict[str, str]:
    """Return a FIFO, a directory and /dev/zero: each exists, none is a regular file."""
    fifo = tmp_path / 'pipe.log'
    os.mkfifo(fifo)
    folder = tmp_path / 'folder.log'
    folder.mkdir()
    return {'a FIFO (named pipe)': str(fifo), 'a directory': str(folder),
            'a character device': '/dev/zero'}


# --- 5: aliases ---------------------------------------------------------------------------
def test_an_alias_bomb_as_a_mapping_file_is_refused_naming_the_file(tmp_path):
    mapping = tmp_path / 'bomb.yaml'
    mapping.write_text(alias_bomb())
    assert len(mapping.read_bytes()) < 600
    dbc, _ = profile_files('foxbms2')
    with pytest.raises(MappingError) as info:
        load_plan(str(dbc), str(mapping))
    assert f"mapping_file '{mapping}'" in str(info.value), info.value
    assert f'more than {ALIAS_VALUES_LIMIT} values once expanded' in str(info.value)


def test_a_few_aliases_still_load():
    text = 'common: &c {scale: 0.1, unit: V}\na: *c\nb: {<<: *c, unit: A}\n'
    assert load_yaml(text, 'mapping x')['b'] == {'scale': 0.1, 'unit': 'A'}


def test_an_alias_to_itself_is_refused():
    with pytest.raises(ConfigError, match=r"mapping x: the YAML alias \*a .*refers to itself"):
        load_yaml('a: &a [1, *a]\n', 'mapping x')


def test_a_params_file_takes_no_alias_as_rcl(tmp_path):
    params = tmp_path / 'alias.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: &d [ams]\n    other: *d\n')
    with pytest.raises(ConfigError) as info:
        load_parameters(str(params), NODE)
    assert f'params file {params}: YAML aliases (*d, line 4) are not allowed' \
        in str(info.value), info.value


def test_a_params_file_bomb_is_refused_by_log2bag_at_once(tmp_path, capsys):
    params = tmp_path / 'bomb.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [ams]\n'
                      + ''.join('    ' + line + '\n' for line in alias_bomb().splitlines()))
    log = tmp_path / 'one.log'
    log.write_text('(0.000000) vcan0 123#00\n')
    assert log2bag([str(log), str(tmp_path / 'bag'), '--params-file', str(params)]) == 2
    err = capsys.readouterr().err
    assert f'params file {params}: YAML aliases' in err and 'Traceback' not in err, err


# --- 10: not a regular file ---------------------------------------------------------------
def test_file_problem_names_what_the_path_is(special_paths, tmp_path):
    for kind, path in special_paths.items():
        assert file_problem(path) == f'is {kind}, not a regular file'
    assert file_problem(tmp_path / 'missing') == 'does not exist'
    (tmp_path / 'file').write_text('x')
    assert file_problem(tmp_path / 'file') is None


def test_log2bag_says_a_log_is_not_a_regular_file(special_paths, tmp_path, capsys):
    params = tmp_path / 'p.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [ams]\n')
    for kind, path in special_paths.items():
        assert log2bag([path, str(tmp_path / 'bag'), '--params-file', str(params)]) == 2
        err = capsys.readouterr().err
        assert f'is {kind}, not a regular file' in err and 'does not exist' not in err, err


def test_probe_says_a_log_is_not_a_regular_file(special_paths, capsys):
    for kind, path in special_paths.items():
        line = one_line_error(capsys, [path])
        assert f"log file '{path}' is {kind}, not a regular file" in line, line


def test_replay_says_a_log_is_not_a_regular_file(special_paths):
    for kind, path in special_paths.items():
        with pytest.raises(LogFileError, match=re.escape(f'is {kind}, not a regular file')):
            ReplayBus(path)
        with pytest.raises(ConfigError, match=re.escape(f'is {kind}, not a regular file')):
            BusConfig(interface='replay', channel=path).check()


def test_a_mapping_or_dbc_that_is_not_a_regular_file_is_named(special_paths):
    dbc, mapping = profile_files('foxbms2')
    for kind, path in special_paths.items():
        with pytest.raises(MappingError,
                           match=re.escape(f"mapping_file '{path}' is {kind}, not a ")):
            load_plan(str(dbc), path)
        with pytest.raises(MappingError, match=re.escape(f"dbc_file '{path}' is {kind}, not a ")):
            load_plan(path, str(mapping))


def test_a_params_file_that_is_a_directory_is_named(special_paths):
    folder = special_paths['a directory']
    with pytest.raises(ConfigError, match=f"'{folder}' is a directory, not a regular file"):
        load_parameters(folder, NODE)


# --- 4: two sections that apply to the node -----------------------------------------------
SPELLINGS = [('/**', 'ams_can_bridge'), ('/**', '/**/ams_can_bridge'), ('ams_can_bridge', '/*'),
             ('/ams_can_bridge', '/**'), ('/*', '/**')]


def two_sections(first: str, second: str) -> str:
    return (f'{first}:\n  ros__parameters:\n    devices: [ams]\n    commands_allowed: false\n'
            f'{second}:\n  ros__parameters:\n    commands_allowed: true\n')


@pytest.mark.parametrize('first, second', SPELLINGS)
def test_a_key_in_two_sections_that_apply_is_refused_naming_both(tmp_path, first, second):
    params = tmp_path / 'two.yaml'
    params.write_text(two_sections(first, second))
    with pytest.raises(ConfigError) as info:
        load_parameters(str(params), NODE)
    assert (f'commands_allowed is given in two sections that both apply to the node '
            f'/ams_can_bridge: line 4 ({first}: commands_allowed = false) and line 7 '
            f'({second}: commands_allowed = true)') in str(info.value), info.value


def test_sections_of_other_nodes_or_other_keys_are_no_duplicate(tmp_path):
    for second in ('other_node', '/car2/ams_can_bridge', '/*/*'):
        assert duplicate_problems('p', two_sections('/**', second), '/ams_can_bridge') == []
    params = tmp_path / 'split.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [ams]\n'
                      'ams_can_bridge:\n  ros__parameters:\n    commands_allowed: true\n')
    assert load_parameters(str(params), NODE) == {'devices': ['ams'], 'commands_allowed': True}
    # in a namespace: /** and /car2/ams_can_bridge both apply
    assert duplicate_problems('p', two_sections('/**', '/car2/ams_can_bridge'),
                              '/car2/ams_can_bridge')


def test_the_bridge_refuses_a_key_in_two_applying_sections_before_the_adapter(tmp_path):
    err = stopped_before_the_adapter(tmp_path, (
        '/**:\n  ros__parameters:\n    devices: [ams]\n    commands_allowed: false\n'
        '    commands_enabled: true\n'
        '/**/ams_can_bridge:\n  ros__parameters:\n    commands_allowed: true\n'), 'spellings')
    assert ('commands_allowed is given in two sections that both apply to the node '
            '/ams_can_bridge: line 4 (/**: commands_allowed = false) and line 8 '
            '(/**/ams_can_bridge: commands_allowed = true)') in err, err
    assert 'commands ENABLED' not in err and 'heartbeat started' not in err


def test_the_bridge_compares_sections_in_its_namespace(tmp_path):
    peer = SlcanPeer(symlink=tmp_path / 'ttyACM_ns')
    try:
        proc = run_bridge(tmp_path, slcan_yaml(peer, (
            '/**:\n  ros__parameters:\n    devices: [ams]\n    commands_allowed: false\n'
            '/car2/ams_can_bridge:\n  ros__parameters:\n    commands_allowed: true\n')),
            '-r', '__ns:=/car2')
        assert proc.returncode == 2, proc.stderr
        assert_nothing_reached(peer)
    finally:
        peer.shutdown()
    assert 'both apply to the node /car2/ams_can_bridge' in proc.stderr, proc.stderr


def test_node_name_from_argv_follows_the_remap_rules():
    argv = ['bridge', '--ros-args', '-r', '__ns:=car2', '-r', 'other:__node:=x',
            '--remap', f'{NODE}:__node:=left']
    assert node_name_from_argv(argv, NODE) == '/car2/left'
    assert node_name_from_argv(['bridge'], NODE) == '/ams_can_bridge'


def test_the_bridge_names_a_missing_or_special_params_file_with_its_full_path(tmp_path):
    os.mkfifo(tmp_path / 'pipe.yaml')
    for name, problem in (('missing.yaml', 'does not exist'),
                          ('pipe.yaml', 'is a FIFO (named pipe), not a regular file')):
        proc = subprocess.run([bridge_executable(), '--ros-args', '--params-file', name],
                              capture_output=True, text=True, timeout=30, cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert f'params file {tmp_path / name} (given as {name}) {problem}' in proc.stderr, \
            proc.stderr
        assert 'Failed to parse global arguments' not in proc.stderr
