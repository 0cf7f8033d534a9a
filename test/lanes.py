# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Test lanes: the marks ``ros`` (starts rclpy) and ``process`` (starts a process), kept honest.

The inner loop, ``./dev test -m "not ros and not process"``, runs the tests that need neither;
the full suite runs everything. Marks come from:

* the code: a test is marked by the calls (ROS_CALLS, PROCESS_CALLS) in its own source, in
  its fixtures' (module-scoped ones too) and in the helpers of test/ they call, followed
  from name to name (``rigs()`` -> ``Rig`` -> ``rclpy.init(``);
* fixtures by name (ROS_FIXTURES, PROCESS_FIXTURES; ``item.fixturenames`` is the closure);
* an explicit ``@pytest.mark.process`` / ``pytestmark`` where the start is out of sight
  (a library that forks: ament's flake8).

Kept honest at run time, in every lane: an audit hook sees each process a test starts
(``subprocess.Popen``, ``os.fork``, ``os.posix_spawn``, ``os.system``, ...) and a wrapper
of ``rclpy.context.Context.init`` each rclpy context it starts; a test that does either
without its mark fails, naming the mark to add. (Importing rclpy or a message type is
neither: those are plain Python, imported while collecting.) ``LANES_REPORT=<file>`` writes
what each test started, one line per test, to survey a suite.
"""
from __future__ import annotations

import functools
import inspect
import os
import re
import sys
import threading
from typing import Any, Callable, Iterator

import pytest

ROS, PROCESS = 'ros', 'process'
# Fixtures that start rclpy / a process (by name; every test using one gets the mark).
ROS_FIXTURES = frozenset({'rig_factory'})
PROCESS_FIXTURES = frozenset({'pytester'})
# Calls in a test's code, its fixtures' or its helpers' (functions of test/) that start rclpy /
# a process; what they miss, the run-time check names (then mark the test by hand).
ROS_CALLS = ('rclpy.init(', 'ros_context(', 'rigs(', 'Rig(', 'every_device_bridge(')
PROCESS_CALLS = ('subprocess.', 'Popen(', 'os.fork', 'os.system(', 'pty.spawn(', 'multiprocessing')
_NAME = re.compile(r'\b([A-Za-z_][A-Za-z0-9_]*)\s*\(')
# The audit events of a new process (https://docs.python.org/3/library/audit_events.html).
PROCESS_EVENTS = frozenset({'subprocess.Popen', 'os.fork', 'os.forkpty', 'os.posix_spawn',
                            'os.spawn', 'os.exec', 'os.system', 'os.startfile', 'pty.spawn'})


class _Watch:
    """What the running test started: {'ros', 'process'} -> the first thing seen."""

    def __init__(self) -> None:
        self.active = False
        self.seen: dict[str, str] = {}
        self.told: set[str] = set()  # lanes already failed for this test (call, teardown)
        self.lock = threading.Lock()

    def note(self, lane: str, what: str) -> None:
        if self.active:
            with self.lock:
                self.seen.setdefault(lane, what)


WATCH = _Watch()


def _audit(event: str, args: tuple) -> None:
    if event in PROCESS_EVENTS and WATCH.active:
        WATCH.note(PROCESS, f'{event} {_short(args)}')


def _short(args: tuple) -> str:
    text = repr(args[:2])
    return text if len(text) < 160 else text[:160] + '...'


def _watch_rclpy() -> None:
    """Wrap Context.init once, so every rclpy context a test starts is noted."""
    try:
        from rclpy.context import Context
    except ImportError:  # no rclpy in this environment: nothing to start either
        return
    if getattr(Context.init, '_lanes_watched', False):
        return
    original: Callable[..., Any] = Context.init

    @functools.wraps(original)
    def init(self: Any, *args: Any, **kwargs: Any) -> Any:
        WATCH.note(ROS, 'rclpy.context.Context.init')
        return original(self, *args, **kwargs)
    setattr(init, '_lanes_watched', True)
    setattr(Context, 'init', init)


def install() -> None:
    """Install the audit hook (once per process: hooks cannot be removed) and the wrapper."""
    if not getattr(sys, '_ams_lanes_hook', False):
        sys.addaudithook(_audit)
        setattr(sys, '_ams_lanes_hook', True)
    _watch_rclpy()


def pytest_configure(config: pytest.Config) -> None:
    """Start watching (pytest.ini declares the marks)."""
    install()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark every test by what its code, its fixtures' and its helpers' code start."""
    for item in items:
        lanes = item_lanes(item)
        for lane in sorted(lanes):
            if item.get_closest_marker(lane) is None:
                item.add_marker(lane)


def item_lanes(item: pytest.Item) -> set[str]:
    """Return the lanes of one test: its fixtures by name, then the calls in its code."""
    names = set(getattr(item, 'fixturenames', ()))
    lanes = {ROS} if names & ROS_FIXTURES else set()
    if names & PROCESS_FIXTURES:
        lanes.add(PROCESS)
    folder = os.path.dirname(os.path.abspath(str(getattr(item, 'path', ''))))
    functions = [getattr(item, 'function', None)]
    info = getattr(item, '_fixtureinfo', None)
    for defs in (info.name2fixturedefs.values() if info is not None else ()):
        functions += [d.func for d in defs]
    for function in functions:
        if _is_test_code(function, folder):  # pytest's own fixtures: by name only (their
            lanes |= _code_lanes(function, folder)  # docs show os.system calls)
    return lanes


@functools.cache
def _code_lanes(function: Callable[..., Any], folder: str) -> frozenset[str]:
    """Return the lanes a function of the tests starts: its source, the helpers it calls."""
    lanes: set[str] = set()
    seen: set[Any] = set()
    todo = [inspect.unwrap(function)]
    while todo:
        code = todo.pop()
        if code in seen:
            continue
        seen.add(code)
        try:
            source = inspect.getsource(code)
        except (OSError, TypeError):
            continue
        for lane, calls in ((ROS, ROS_CALLS), (PROCESS, PROCESS_CALLS)):
            if any(call in source for call in calls):
                lanes.add(lane)
        scope = getattr(code, '__globals__', None) or vars(sys.modules.get(code.__module__, sys))
        for name in set(_NAME.findall(source)):
            found = scope.get(name)
            if _is_test_code(found, folder):
                todo.append(found)
    return frozenset(lanes)


def _is_test_code(obj: Any, folder: str) -> bool:
    """Tell whether obj is a function or class of a file in the test's folder (test/)."""
    if not (inspect.isfunction(obj) or inspect.isclass(obj)):
        return False
    module = sys.modules.get(getattr(obj, '__module__', ''), None)
    path = getattr(module, '__file__', None) or ''
    return os.path.dirname(os.path.abspath(path)) == folder


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Iterator[None]:
    """Watch setup, call and teardown of one test."""
    WATCH.seen = {}
    WATCH.told = set()
    WATCH.active = True
    try:
        yield
    finally:
        WATCH.active = False


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    """Fail a test that started rclpy or a process without the mark (setup/call: the call)."""
    outcome = yield
    if call.when == 'setup':
        return
    report = outcome.get_result()
    report_path = os.environ.get('LANES_REPORT')
    if report_path and call.when == 'teardown':  # what each test started, for a survey
        with open(report_path, 'a', encoding='utf-8') as stream:
            stream.write(f'{item.nodeid}\t{",".join(sorted(WATCH.seen))}\n')
    with WATCH.lock:
        missing = [(lane, what) for lane, what in sorted(WATCH.seen.items())
                   if item.get_closest_marker(lane) is None and lane not in WATCH.told]
    if missing and report.passed:
        WATCH.told.update(lane for lane, _ in missing)
        report.outcome = 'failed'
        report.longrepr = (
            f'{item.nodeid} is not marked for its lane: ' + '; '.join(
                f'it started {"rclpy" if lane == ROS else "a process"} ({what}) but has no '
                f'@pytest.mark.{lane}' for lane, what in missing)
            + ' (test/lanes.py: mark the test, its module (pytestmark) or its fixture, so '
            '`./dev test -m "not ros and not process"` stays the fast inner loop)')
