# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ament flake8 over the package, tests, benchmarks, launch files, scripts, doc/ (ROS style)."""
import pytest
from ament_flake8.main import main_with_errors


@pytest.mark.flake8
@pytest.mark.linter
@pytest.mark.process  # flake8 checks the files in worker processes (multiprocessing)
def test_flake8():
    rc, errors = main_with_errors(argv=['ams_can_bridge', 'test', 'bench', 'launch', 'scripts',
                                        'doc', 'setup.py'])
    assert rc == 0, 'Found %d code style errors / warnings:\n' % len(errors) + '\n'.join(errors)
