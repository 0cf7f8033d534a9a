# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Test-wide settings: DDS stays on this machine, each run on its own domain; hypothesis profiles.

The domain: every test run (one pytest process) reserves a ROS_DOMAIN_ID of TEST_DOMAINS
through ROS's ``domain_coordinator`` (it holds a local port per domain for the whole run),
so two runs on one machine never share one, whatever ROS_DOMAIN_ID the shell has; the
processes the tests start inherit it. ``./dev`` and the demo take theirs from 100..149 and
the benchmarks from 150..199 (doc/getting_started.md), so a test never meets them either.

Hypothesis: the ``ci`` profile (default) is derandomized, a fixed seed, so a CI run is
reproducible; ``HYPOTHESIS_PROFILE=long ./dev test`` draws new random examples, many more
of them (``examples(n)`` scales the explicit counts of the slow node-level fuzz tests).
"""
import itertools
import os
from typing import Callable

from domain_coordinator import domain_id
from hypothesis import HealthCheck, settings
import pytest

# The lanes (marks ros / process, checked at run time): test/lanes.py.
from lanes import (pytest_collection_modifyitems, pytest_configure,  # noqa: F401 (hooks)
                   pytest_runtest_makereport, pytest_runtest_protocol)

# Network rule: never let DDS discovery leave the machine, and keep test runs apart.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
TEST_DOMAINS = range(200, 233)  # 232: the highest domain Fast DDS's port mapping allows


def _test_domains() -> Callable[[], int]:
    """Return domain_coordinator's selector: TEST_DOMAINS in turn, from this process's place."""
    turn = itertools.count(os.getpid())
    return lambda: TEST_DOMAINS[next(turn) % len(TEST_DOMAINS)]


# Entered for the whole run and never left: the port that reserves the domain stays open
# until this process ends (kept in a global so that it is not collected).
_RESERVATION = domain_id(selector=_test_domains())
try:
    os.environ['ROS_DOMAIN_ID'] = str(_RESERVATION.__enter__())
except RuntimeError as exc:
    raise RuntimeError(f'every ROS domain of {TEST_DOMAINS} is taken by another test run on '
                       'this machine: wait for one to end') from exc


def pytest_report_header() -> str:
    """Say which domain this run has (to find its traffic with ros2 tools)."""
    return (f"ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']} (reserved for this run), "
            'ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST')


settings.register_profile('ci', derandomize=True, deadline=None, database=None,
                          print_blob=True)
settings.register_profile('long', deadline=None, max_examples=1000,
                          suppress_health_check=[HealthCheck.too_slow])
PROFILE = os.environ.get('HYPOTHESIS_PROFILE', 'ci')
settings.load_profile(PROFILE)
LONG_FACTOR = 20  # how many more examples the long profile runs in the node-level fuzz


@pytest.fixture
def rig_factory():
    """
    Make bridges on a python-can virtual bus (``command_rig.Rig``); all closed afterwards.

    The one bridge-on-a-virtual-bus fixture: ``rig_factory(params, **kwargs)`` returns a
    started Rig (node, executor thread, a bus capture that also injects frames, recorded
    topics and diagnostics, waits through helpers.wait_for, service calls, parameter sets,
    failures escaping callbacks or threads). A module-scoped user takes ``command_rig.rigs``.
    """
    from command_rig import rigs  # imports rclpy: only for the tests that use it
    with rigs() as make:
        yield make


@pytest.fixture
def bench_factory():
    """
    Make ROS-free command benches (``command_bench.Bench``); all closed afterwards.

    ``bench_factory(params, **kwargs)`` takes the parameters a ``rig_factory`` takes and
    returns a bridge's command side (devices, gate, the one pipeline, the periodic senders)
    on a virtual bus, with a capture: a command's walk to the bus without rclpy.
    """
    from command_bench import Bench
    made = []

    def make(params, **kwargs):
        bench = Bench(params, **kwargs)
        made.append(bench)
        return bench
    yield make
    for bench in reversed(made):
        bench.close()


@pytest.fixture
def ros():
    """
    Give a listener node and its executor in a ROS context of its own: ``(node, executor)``.

    For the tests that watch an installed executable (a subprocess on this run's domain)
    from this process; the context is shut down afterwards.
    """
    import rclpy  # only for the tests that use it: the fast lanes import no ROS
    from rclpy.executors import SingleThreadedExecutor
    from helpers import ros_context
    with ros_context() as ctx:
        node = rclpy.create_node('slcan_test_listener', context=ctx)
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(node)
        yield node, executor
        executor.shutdown()
        node.destroy_node()


def examples(n: int) -> int:
    """Return n examples in CI, LONG_FACTOR x n with HYPOTHESIS_PROFILE=long."""
    return n * LONG_FACTOR if PROFILE == 'long' else n
