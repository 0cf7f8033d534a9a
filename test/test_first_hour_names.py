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
