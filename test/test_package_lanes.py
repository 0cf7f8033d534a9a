# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The lane marks stay honest: a test that starts rclpy or a process without its mark fails.

A small suite in a temporary folder, run by pytest with this suite's lane hooks (test/lanes.py):
its tests start things directly (marked by what their code calls) or through a helper outside
the tests' folder, which no scan follows (caught at run time).
"""
from pathlib import Path
import subprocess
import sys

HERE = Path(__file__).resolve().parent

CONFTEST = f'''
import os
import sys
sys.path.insert(0, {str(HERE)!r})
sys.path.insert(0, os.path.join(os.path.dirname(__file__), 'lib'))
from lanes import (pytest_collection_modifyitems, pytest_configure,  # noqa: F401
                   pytest_runtest_makereport, pytest_runtest_protocol)
'''
INI = '''[pytest]
markers =
    ros: starts rclpy
    process: starts a process
'''
# Out of the tests' folder: what these start, only the run-time check sees.
STARTERS = '''
import os


def start_process():
    return os.popen('true').read()


def start_rclpy():
    import rclpy
    from rclpy.context import Context
    context = Context()
    rclpy.init(context=context)
    rclpy.shutdown(context=context)
'''
TESTS = '''
import subprocess

import pytest

from starters import start_process, start_rclpy


def test_plain():
    assert 1 + 1 == 2


def test_process_unmarked():
    start_process()


def test_rclpy_unmarked():
    start_rclpy()


@pytest.mark.process
def test_process_marked():
    start_process()


@pytest.mark.ros
def test_rclpy_marked():
    start_rclpy()


def test_process_seen_in_its_code():
    subprocess.run(['true'], check=True, timeout=30)
'''


def run_inner(folder: Path, *args: str) -> str:
    (folder / 'conftest.py').write_text(CONFTEST)
    (folder / 'pytest.ini').write_text(INI)
    (folder / 'lib').mkdir()
    (folder / 'lib' / 'starters.py').write_text(STARTERS)
    (folder / 'test_inner.py').write_text(TESTS)
    result = subprocess.run([sys.executable, '-m', 'pytest', '-p', 'no:cacheprovider', '-rf',
                             *args], cwd=folder, capture_output=True, text=True, timeout=300)
    return result.stdout + result.stderr


def test_an_unmarked_test_that_starts_a_process_or_rclpy_fails_naming_the_mark(tmp_path):
    out = run_inner(tmp_path)
    assert '2 failed, 4 passed' in out, out
    assert ('test_inner.py::test_process_unmarked is not marked for its lane: it started a '
            "process (subprocess.Popen ('/bin/sh', ['/bin/sh', '-c', 'true'])) but has no "
            '@pytest.mark.process') in out, out
    assert ('test_inner.py::test_rclpy_unmarked is not marked for its lane: it started rclpy '
            '(rclpy.context.Context.init) but has no @pytest.mark.ros') in out, out
    assert 'FAILED test_inner.py::test_process_unmarked' in out
    assert 'FAILED test_inner.py::test_rclpy_unmarked' in out


def test_the_inner_loop_runs_no_marked_test_and_still_catches_the_unmarked(tmp_path):
    out = run_inner(tmp_path, '-m', 'not ros and not process', '-v')
    assert '2 failed, 1 passed, 3 deselected' in out, out
    assert 'test_process_seen_in_its_code' not in out  # marked by the call in its code
    assert 'test_inner.py::test_plain PASSED' in out, out
