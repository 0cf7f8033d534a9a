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
    lines = collected('test/test_package_executables.py', 'test/test_device_configs.py')
    ids = [line for line in lines if '::' in line]
    files = {line.split('::')[0] for line in ids}
    assert files == {'test/test_package_executables.py', 'test/test_device_configs.py'}, lines[-5:]


def test_without_a_path_the_whole_suite_is_collected():
    lines = collected('-k', 'no_test_is_called_like_this')
    summary = lines[-1]
    assert 'no tests collected' in summary, lines[-5:]
    deselected = int(summary.split('(')[1].split()[0])
    assert deselected > 1000, summary  # every test of test/, none of them selected


def test_a_subsystem_s_name_runs_its_files_only():
    from subsystems import BY_NAME
    result = subprocess.run(['bash', str(ROOT / 'dev'), 'test', 'pack', '--collect-only', '-q',
                             '-p', 'no:cacheprovider'], cwd=ROOT, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    ids = [line for line in result.stdout.splitlines() if '::' in line]
    files = {line.split('::')[0] for line in ids}
    assert files == {f'test/{p.name}' for p in BY_NAME['pack'].files()}, ids[-5:]
    assert len(files) >= 4


def test_an_unknown_subsystem_is_named_with_the_choices():
    result = subprocess.run(['bash', str(ROOT / 'dev'), 'test', 'packs'], cwd=ROOT,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 2
    assert ('./dev test packs: no such subsystem and no such path; give one of protocol, '
            'device,') in result.stderr, result.stderr
