# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""./dev test: the whole suite by default, only the files or directories given otherwise."""
from pathlib import Path
import subprocess

ROOT = Path(__file__).resolve().parent.parent


def collected(*args: str) -> list[str]:
    result = subprocess.run(['bash', str(ROOT / 'dev'), 'test', '--collect-only', '-q',
                             '-p', 'no:cacheprovider', *args], cwd=ROOT, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode in (0, 5), result.stdout[-2000:] + result.stderr[-2000:]
    return result.stdout.splitlines()


def test_the_files_given_replace_the_whole_suite():
    lines = collected('test/test_executables.py', 'test/test_device_configs.py')
    ids = [line for line in lines if '::' in line]
    files = {line.split('::')[0] for line in ids}
    assert files == {'test/test_executables.py', 'test/test_device_configs.py'}, lines[-5:]


def test_without_a_path_the_whole_suite_is_collected():
    lines = collected('-k', 'no_test_is_called_like_this')
    summary = lines[-1]
    assert 'no tests collected' in summary, lines[-5:]
    deselected = int(summary.split('(')[1].split()[0])
    assert deselected > 1000, summary  # every test of test/, none of them selected
