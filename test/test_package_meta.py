# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What the package says about itself: version, changelog, descriptions, --help, dependencies.

One version in package.xml, setup.py and the top of CHANGELOG.rst (the ROS changelog format,
REP 132, as catkin_pkg reads it for bloom); every device type of the registry named in the
package.xml and setup.py descriptions and in ``bridge --help``; every ROS package the code
imports declared in package.xml.
"""
from __future__ import annotations

import ast
from pathlib import Path
import re
import xml.etree.ElementTree as ElementTree

from catkin_pkg.changelog import get_changelog_from_path
import pytest

from ams_can_bridge import registry
from ams_can_bridge.ros import bridge_main

ROOT = Path(__file__).resolve().parent.parent
MANIFEST = ElementTree.parse(ROOT / 'package.xml').getroot()
# How the descriptions name each device type; a new type must be added here (and there).
NAMED = {'ams': 'AMS', 'ivt_s': 'IVT-S', 'evms3': 'EVMS3', 'bms16': 'BMS16', 'sma': 'SMA',
         'dbc': 'DBC', 'pack': 'pack'}
ROS_PACKAGE = re.compile(r'rclpy|launch(_ros)?|\w+_(msgs|srvs|interfaces)')


def setup_keywords() -> dict[str, object]:
    """Return the literal keyword arguments of setup.py's setup() call."""
    tree = ast.parse((ROOT / 'setup.py').read_text(encoding='utf-8'))
    call = next(node for node in ast.walk(tree)
                if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'setup')
    found = {}
    for keyword in call.keywords:
        try:
            found[keyword.arg] = ast.literal_eval(keyword.value)
        except ValueError:
            pass  # computed (packages, data_files)
    return found


# catkin_pkg 1.1.1 calls docutils' Node.traverse, deprecated in the docutils Sphinx pins
@pytest.mark.filterwarnings('ignore:nodes.Node.traverse:DeprecationWarning')
def test_one_version_in_package_xml_setup_py_and_the_changelog():
    version = MANIFEST.findtext('version')
    assert re.fullmatch(r'\d+\.\d+\.\d+', version)
    assert setup_keywords()['version'] == version
    text = (ROOT / 'CHANGELOG.rst').read_text(encoding='utf-8')
    assert text.startswith('^' * 36 + '\nChangelog for package ams_can_bridge\n' + '^' * 36)
    changelog = get_changelog_from_path(str(ROOT / 'CHANGELOG.rst'), 'ams_can_bridge')
    versions = [(v, date, content) for v, date, content in changelog.foreach_version()]
    assert versions, 'catkin_pkg finds no "X.Y.Z (YYYY-MM-DD)" section in CHANGELOG.rst'
    newest, date, content = versions[0]
    assert newest == version, f'CHANGELOG.rst starts with {newest}, package.xml says {version}'
    assert date.year >= 2026 and str(content[0]).startswith('* ')


def test_the_descriptions_and_bridge_help_name_every_device_type(capsys):
    assert set(NAMED) == set(registry.DEVICE_TYPES)
    manifest = ' '.join(MANIFEST.findtext('description').split())
    setup_description = setup_keywords()['description']
    assert bridge_main.main(['bridge', '--help']) == 0
    usage = capsys.readouterr().out
    types = re.search(r'^  <name>\.type +(.+) \(default: the instance name\)$', usage,
                      re.MULTILINE)
    assert types and types.group(1).split(', ') == list(registry.DEVICE_TYPES)
    for device_type, name in NAMED.items():
        assert name in manifest, f'package.xml <description> does not name {name}'
        assert name in setup_description, f'setup.py description does not name {name}'
        assert name in usage.split('main parameters:')[0], f'bridge --help: {name}'


def test_every_ros_package_the_code_imports_is_an_exec_depend():
    imported = set()
    for path in [*(ROOT / 'ams_can_bridge').rglob('*.py'), *(ROOT / 'launch').glob('*.py')]:
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                imported.add(node.module.split('.')[0])
            elif isinstance(node, ast.Import):
                imported.update(alias.name.split('.')[0] for alias in node.names)
    ros = {name for name in imported if ROS_PACKAGE.fullmatch(name)}
    assert {'rclpy', 'sensor_msgs', 'std_srvs'} <= ros
    depends = {e.text for e in MANIFEST if e.tag in ('exec_depend', 'depend')}
    assert ros - depends == set(), 'imported but not an <exec_depend> in package.xml'
