# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ament pep257 docstring conventions over the package, tests, scripts and doc/."""
import pytest
from ament_pep257.main import main


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc = main(argv=['ams_can_bridge', 'test', 'scripts', 'doc'])
    assert rc == 0, 'Found code style errors / warnings'
