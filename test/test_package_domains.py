# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ROS domains and discovery: what keeps a test run, ./dev and the demo apart (issue 38.3, 38.4).

Each test run has a domain of its own, ./dev and the demo take theirs from another range,
and `source .venv/bin/activate` keeps discovery on this machine.
"""
import os
from pathlib import Path
import re
import socket
import subprocess
import sys

from domain_coordinator import domain_id
from domain_coordinator.impl import PORT_BASE
import pytest

import conftest
from ams_can_bridge.ros import demo

ROOT = Path(__file__).resolve().parents[1]


def test_this_run_holds_a_test_domain_no_other_run_can_take():
    mine = int(os.environ['ROS_DOMAIN_ID'])
    assert mine in conftest.TEST_DOMAINS
    taken = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        with pytest.raises(OSError):  # the reservation: another run's coordinator skips it
            taken.bind(('', PORT_BASE + mine))
    finally:
        taken.close()
    with domain_id(selector=conftest._test_domains()) as other:  # as a second run would
        assert other in conftest.TEST_DOMAINS and other != mine


def test_dev_the_demo_and_the_tests_never_share_a_range():
    script = (ROOT / 'dev').read_text()
    first = int(re.search(r'DEV_DOMAINS_FIRST=(\d+)', script).group(1))
    count = int(re.search(r'DEV_DOMAINS_COUNT=(\d+)', script).group(1))
    assert '$(( ($$ % DEV_DOMAINS_COUNT) + DEV_DOMAINS_FIRST ))' in script
    dev = set(range(first, first + count))
    assert dev == set(demo.DEMO_DOMAINS)
    assert not dev & set(conftest.TEST_DOMAINS)
    assert max(conftest.TEST_DOMAINS) <= 232  # Fast DDS's highest domain on its port map
    ci = (ROOT / '.ci' / 'run').read_text()
    assert f'$(( ($$ % {count}) + {first} ))' in ci


@pytest.mark.process
def test_processes_started_by_tests_share_the_runs_domain():
    done = subprocess.run([sys.executable, '-c', 'import os; print(os.environ["ROS_DOMAIN_ID"],'
                           ' os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"])'],
                          capture_output=True, text=True, timeout=60)
    assert done.stdout.split() == [os.environ['ROS_DOMAIN_ID'], 'LOCALHOST']


@pytest.mark.process
def test_activate_keeps_dds_on_this_machine():
    """README step 2: `source .venv/bin/activate` sets ROS_AUTOMATIC_DISCOVERY_RANGE."""
    venv = Path(sys.executable).parent.parent
    activate = venv / 'bin' / 'activate'
    if not (ROOT / '.venv').exists() or venv.resolve() != (ROOT / '.venv').resolve():
        pytest.fail(f'run through ./dev: this Python ({sys.executable}) is not ./dev\'s .venv')
    setup = subprocess.run(['bash', str(ROOT / 'dev'), 'setup'], capture_output=True,
                           text=True, timeout=600)
    assert setup.returncode == 0, setup.stderr[-2000:]
    env = {k: v for k, v in os.environ.items() if not k.startswith('ROS_AUTOMATIC')}
    shown = subprocess.run(['bash', '-c', f'source {activate} && '
                            'echo "$ROS_AUTOMATIC_DISCOVERY_RANGE" && command -v bridgectl'],
                           capture_output=True, text=True, timeout=60, env=env)
    assert shown.stdout.splitlines() == ['LOCALHOST', str(venv / 'bin' / 'bridgectl')], shown
    # ./dev setup adds it once, however often it runs
    assert activate.read_text().count('export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST') == 1
