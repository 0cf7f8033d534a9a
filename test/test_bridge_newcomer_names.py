# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Issue 38, points 5 and 10: a bridge name nothing shadows, and a help that needs no ROS.

``bridge`` is also iproute2's ``/usr/sbin/bridge``: the same program is installed as
``ams-can-bridge``, its help says why, and it names the installed example params files'
folder itself (``ros2 pkg prefix`` does not exist on the pip path).
"""
from __future__ import annotations

from pathlib import Path
import re
import subprocess

from ams_can_bridge.ros import bridge_main
from executables import package_executable

ROOT = Path(__file__).resolve().parents[1]


def test_ams_can_bridge_is_the_bridge_under_a_second_name():
    scripts = dict(re.findall(r"'([\w-]+) = ([\w.:]+)'", (ROOT / 'setup.py').read_text()))
    assert scripts['ams-can-bridge'] == scripts['bridge'] == 'ams_can_bridge.ros.bridge_main:main'
    proc = subprocess.run([package_executable('ams-can-bridge'), '--help'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith('usage: bridge') and 'ams-can-bridge [-h] --ros-args' \
        in proc.stdout
    assert "/usr/sbin/bridge" in proc.stdout and "Use\n'ams-can-bridge' there" in proc.stdout


def test_bridge_help_prints_the_installed_config_folder(capsys):
    assert bridge_main.main(['bridge', '--help']) == 0
    usage = capsys.readouterr().out
    assert 'ros2 pkg prefix' not in usage
    line = next(line.strip() for line in usage.splitlines() if line.endswith('/*.yaml'))
    folder = Path(line[:-len('/*.yaml')])
    assert folder.is_absolute() and (folder / 'bms16.yaml').is_file(), line


def test_the_install_check_runs_the_second_name_on_both_paths():
    text = (ROOT / 'scripts' / 'check_install.sh').read_text()
    assert 'lib/ams_can_bridge/ams-can-bridge' in text  # colcon
    assert 'for exe in bridge ams-can-bridge ' in text and 'venv/bin/ams-can-bridge' in text
    for page in ('getting_started.md', 'real_bus.md'):
        assert 'ams-can-bridge' in (ROOT / 'doc' / page).read_text(), page


# The Python keys of package.xml as ros/rosdistro's rosdep/python.yaml has them (checked at
# its commit 8468e88c, 2026-08-22): cantools and rosbags only as pip keys, canmatrix not at all.
ROSDEP_PYTHON_KEYS = {'python3-can', 'python3-cantools-pip', 'python3-serial', 'python3-yaml',
                      'python3-rosbags-pip', 'python3-pytest', 'python3-hypothesis'}


def install_section() -> str:
    text = (ROOT / 'doc' / 'getting_started.md').read_text()
    return text.split('\n## Installing in a ROS 2 workspace\n', 1)[1].split('\n## ', 1)[0]


def pins(path: Path) -> dict[str, str]:
    return dict(re.findall(r'^([\w-]+)==([\w.]+)', path.read_text(), re.M))


def test_the_workspace_recipe_is_rosdep_first_with_real_keys_and_a_pinned_fallback():
    """Issue 38, 9: `pip install` into the system Python fails on Ubuntu 24.04 (PEP 668)."""
    blocks = re.findall(r'```bash\n(.*?)```', install_section(), re.S)
    assert 'rosdep install --from-paths src -y --ignore-src' in blocks[0]
    assert 'pip install' not in blocks[0]  # PEP 668: refused on the system Python
    manifest = (ROOT / 'package.xml').read_text()
    python_keys = set(re.findall(r'<(?:exec_|test_)?depend>(python3-[\w-]+)</', manifest))
    assert python_keys <= ROSDEP_PYTHON_KEYS, python_keys - ROSDEP_PYTHON_KEYS
    # the fallback: a venv that sees ROS, the versions CI tests, colcon run from the venv
    fallback = blocks[1]
    assert 'python3 -m venv --system-site-packages' in fallback
    assert 'python -m colcon build' in fallback and 'COLCON_IGNORE' in fallback
    tested = pins(ROOT / 'requirements.txt') | pins(ROOT / 'requirements-dev.txt')
    given = dict(re.findall(r'([\w-]+)==([\w.]+)', install_section()))
    assert {'python-can', 'cantools', 'rosbags', 'canmatrix'} <= set(given)
    assert all(tested[name] == version for name, version in given.items()), given
    assert 'PIP_BREAK_SYSTEM_PACKAGES' in install_section()
