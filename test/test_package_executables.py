# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Tests start this package's executables, never a PATH namesake (iproute2's /usr/sbin/bridge).

test/executables.py looks where the package installs them (the venv next to this Python, a
colcon prefix's lib/ams_can_bridge/) and takes a file only if it is one of ours.
"""
import os
from pathlib import Path
import shutil

import pytest

from executables import is_ours, package_executable

NAMES = ('bridge', 'simulator', 'demo', 'monitor', 'log2bag')
IPROUTE2 = '#!/bin/sh\necho "Usage: bridge [ OPTIONS ] OBJECT { COMMAND | help }"\n'


def fake(folder: Path, name: str, text: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text)
    path.chmod(0o755)
    return path


@pytest.fixture
def path_with_namesakes(tmp_path, monkeypatch):
    """PATH starts with a folder holding a foreign executable of every name."""
    folder = tmp_path / 'sbin'
    for name in NAMES:
        fake(folder, name, IPROUTE2)
    monkeypatch.setenv('PATH', f'{folder}{os.pathsep}{os.environ["PATH"]}')
    assert shutil.which('bridge') == str(folder / 'bridge')
    return folder


@pytest.mark.parametrize('name', NAMES)
def test_each_executable_is_ours_with_a_namesake_first_on_path(name, path_with_namesakes):
    found = Path(package_executable(name))
    assert found.parent != path_with_namesakes and found.name == name
    assert is_ours(found) and not is_ours(path_with_namesakes / name)


def colcon_install(root: Path, script: str) -> tuple[Path, Path]:
    """Lay out a colcon install prefix of the package; return (prefix, its bridge)."""
    prefix = root / 'ws' / 'install' / 'ams_can_bridge'
    package = prefix / 'lib' / 'python3.11' / 'site-packages' / 'ams_can_bridge'
    package.mkdir(parents=True)
    (package / '__init__.py').write_text('')
    return prefix, fake(prefix / 'lib' / 'ams_can_bridge', 'bridge', script)


# What colcon (setuptools) writes for a console script: it names the distribution only.
COLCON_SCRIPT = """#!/usr/bin/python3
# EASY-INSTALL-ENTRY-SCRIPT: 'ams-can-bridge==0.1.0','console_scripts','bridge'
__requires__ = 'ams-can-bridge==0.1.0'
"""


def test_a_colcon_install_is_found_where_the_package_comes_from(tmp_path, path_with_namesakes):
    # colcon: this Python's folder has no bridge of ours (a system python3, or a venv without
    # the package); the workspace's is in <prefix>/lib/ams_can_bridge, not on PATH
    prefix, installed = colcon_install(tmp_path, COLCON_SCRIPT)
    python_dir = tmp_path / 'usr-bin'
    fake(python_dir, 'bridge', IPROUTE2)
    package_file = str(prefix / 'lib' / 'python3.11' / 'site-packages' / 'ams_can_bridge'
                       / '__init__.py')
    assert package_executable('bridge', bin_dir=python_dir, prefixes=[],
                              package_file=package_file) == str(installed)


def test_a_colcon_install_on_the_ament_prefix_path_is_found(tmp_path, path_with_namesakes):
    prefix, installed = colcon_install(tmp_path, COLCON_SCRIPT)
    python_dir = tmp_path / 'usr-bin'
    fake(python_dir, 'bridge', IPROUTE2)
    found = package_executable('bridge', bin_dir=python_dir,
                               prefixes=[str(tmp_path / 'other'), str(prefix)],
                               package_file=str(tmp_path / 'src' / 'ams_can_bridge' / 'x.py'))
    assert found == str(installed)


def test_no_install_of_ours_is_a_clear_failure_not_a_namesake(tmp_path, path_with_namesakes):
    python_dir = tmp_path / 'usr-bin'
    fake(python_dir, 'bridge', IPROUTE2)
    with pytest.raises(AssertionError) as failed:
        package_executable('bridge', bin_dir=python_dir, prefixes=[str(tmp_path / 'none')],
                           package_file=str(tmp_path / 'src' / 'ams_can_bridge' / 'x.py'))
    message = str(failed.value)
    assert "executable 'bridge' is not installed" in message and 'colcon build' in message
    assert str(python_dir) in message and str(path_with_namesakes) not in message
