"""README stays true to the code: every parameter and service the node declares is in it."""
from pathlib import Path

import pytest

from ams_can_bridge import registry
from helpers import every_device_bridge

README = (Path(__file__).resolve().parents[1] / 'README.md').read_text()
ROS_BUILTIN = {'use_sim_time', 'start_type_description_service'}
PER_INSTANCE = {'type', 'frame_id', 'location', 'serial_number'}  # documented as <name>.key


@pytest.fixture(scope='module')
def node():
    with every_device_bridge('readme-test') as bridge:
        yield bridge


def test_readme_names_every_parameter(node):
    missing = []
    for name in node._parameters:
        if name in ROS_BUILTIN:
            continue
        instance, _, key = name.partition('.')
        documented = f'`{name}`' in README or (
            instance in registry.DEVICE_TYPES and key in PER_INSTANCE
            and f'`<name>.{key}`' in README)
        if not documented:
            missing.append(name)
    assert not missing, f'README.md does not document: {missing} (scripts/param_table.py)'


def test_readme_names_every_service(node):
    services = [name for name, _ in node.get_service_names_and_types_by_node(
        node.get_name(), node.get_namespace())]
    ours = [s for s in services if s.split('/')[-2] in registry.DEVICE_TYPES]
    assert len(ours) >= 18, services
    missing = [s for s in ours if f'`{s.split("/")[-1]}`' not in README]
    assert not missing, f'README.md does not document the services {missing}'


def test_readme_has_the_two_commands_and_every_config_file():
    assert './dev demo' in README and './dev test' in README
    for path in (Path(__file__).resolve().parents[1] / 'config').glob('*.yaml'):
        assert f'config/{path.name}' in README, path.name


def test_failure_mode_table_names_tests_that_exist():
    import ast
    import re
    section = README.split('## Failure modes', 1)[1].split('\n## ', 1)[0]
    named = re.findall(r'`(test_\w+\.py)::(test_\w+)`', section)
    assert len(named) >= 25, named
    here = Path(__file__).resolve().parent
    missing = []
    for path, name in named:
        source = here / path
        tests = {n.name for n in ast.parse(source.read_text()).body
                 if isinstance(n, ast.FunctionDef)} if source.is_file() else set()
        if name not in tests:
            missing.append(f'{path}::{name}')
    assert not missing, f'README failure-mode table names tests that do not exist: {missing}'
