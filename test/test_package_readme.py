# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
README and doc/ stay true to the code.

The parameter tables name every parameter the node declares; the pages name every config file
and only failure-mode tests that exist.

Every service of the node is in the generated topics/services page: test_package_docs.py
checks that table against a running bridge with every device type
(``test_the_interface_table_is_what_a_running_bridge_offers``), so it is not checked here.
"""
import ast
from pathlib import Path
import re
import subprocess
import sys

import pytest

from ams_can_bridge import registry
from helpers import every_device_bridge

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / 'README.md').read_text()
DOC = ROOT / 'doc'
ROS_BUILTIN = {'use_sim_time', 'start_type_description_service'}
PER_INSTANCE = {'type', 'frame_id', 'location', 'serial_number'}  # documented as <name>.key


def page(name: str) -> str:
    """Return one page of doc/ as written (Markdown)."""
    return (DOC / f'{name}.md').read_text()


@pytest.fixture(scope='module')
def parameter_tables() -> str:
    """Return the tables of doc/parameters.md, as the doc build generates them."""
    return subprocess.run([sys.executable, str(ROOT / 'scripts' / 'param_table.py')],
                          capture_output=True, text=True, timeout=60, cwd=ROOT,
                          check=True).stdout


@pytest.fixture(scope='module')
def node():
    with every_device_bridge('readme-test') as bridge:
        yield bridge


def test_the_parameter_page_names_every_parameter_the_node_declares(node, parameter_tables):
    assert '```{generated} parameters\n```' in page('parameters')  # the page is the tables
    missing = []
    for name in node._parameters:
        if name in ROS_BUILTIN:
            continue
        instance, _, key = name.partition('.')
        documented = f'`{name}`' in parameter_tables or (
            instance in registry.DEVICE_TYPES and key in PER_INSTANCE
            and f'`<name>.{key}`' in parameter_tables)
        if not documented:
            missing.append(name)
    assert not missing, f'scripts/param_table.py does not list: {missing}'


def test_the_two_commands_are_in_the_readme_and_every_config_file_in_doc():
    assert './dev demo' in README and './dev test' in README
    assert './dev test -m "not ros and not process"' in README
    pages = '\n'.join(p.read_text() for p in DOC.glob('*.md'))
    for path in (ROOT / 'config').glob('*.yaml'):
        assert f'config/{path.name}' in pages, path.name


def test_the_readme_links_every_page_of_doc():
    for path in DOC.glob('*.md'):
        assert f'(doc/{path.name}' in README, path.name


def test_failure_mode_table_names_tests_that_exist():
    named = re.findall(r'`(test_\w+\.py)::(test_\w+)`', page('failure_modes'))
    assert len(named) >= 25, named
    here = Path(__file__).resolve().parent
    missing = []
    for path, name in named:
        source = here / path
        tests = {n.name for n in ast.parse(source.read_text()).body
                 if isinstance(n, ast.FunctionDef)} if source.is_file() else set()
        if name not in tests:
            missing.append(f'{path}::{name}')
    assert not missing, f'doc/failure_modes.md names tests that do not exist: {missing}'
