"""
Test-wide settings: DDS stays on this machine, each run on its own domain; hypothesis profiles.

Hypothesis: the ``ci`` profile (default) is derandomized, a fixed seed, so a CI run is
reproducible; ``HYPOTHESIS_PROFILE=long ./dev test`` draws new random examples, many more
of them (``examples(n)`` scales the explicit counts of the slow node-level fuzz tests).
"""
import os
import random

from hypothesis import HealthCheck, settings
import pytest

# The lanes (marks ros / process, checked at run time): test/lanes.py.
from lanes import (pytest_collection_modifyitems, pytest_configure,  # noqa: F401 (hooks)
                   pytest_runtest_makereport, pytest_runtest_protocol)

# Network rule: never let DDS discovery leave the machine, and keep test runs apart.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random(os.getpid()).randint(100, 200)))

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


def examples(n: int) -> int:
    """Return n examples in CI, LONG_FACTOR x n with HYPOTHESIS_PROFILE=long."""
    return n * LONG_FACTOR if PROFILE == 'long' else n
