# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Periodic work on one plain thread, off the ROS executor.

rclpy's executors rebuild their wait set on every wake-up, which costs more than the work
a 5 Hz watch does. One thread that sleeps until the next task is due wakes for the task
alone, and leaves the executor asleep until a service is called.
"""
from __future__ import annotations

import logging
import threading
import time
from typing import Callable

from ams_can_bridge.errors import ConfigError

_ERROR_LOG_EVERY = 5.0  # s between log lines for a task that keeps failing


class TimerThread:
    """Run callbacks, each every its own period (no drift), on one thread until stopped."""

    def __init__(self, name: str, logger: logging.Logger | None = None) -> None:
        """Create the (not yet started) thread; ``name`` names it in stack dumps."""
        self.name = name
        self._log = logger or logging.getLogger('ams_can_bridge.periodic')
        self._tasks: list[list] = []  # [next due (monotonic), period, callback, last log]
        # Held while the thread runs; stop() releases it to wake the thread at once. A plain
        # lock's timed acquire is one call; an Event's wait builds a Condition waiter each
        # time (more CPU per wake-up: bench/README.md).
        self._wake = threading.Lock()
        self._stopping = True
        self._thread: threading.Thread | None = None

    def every(self, period: float, callback: Callable[[], None]) -> None:
        """Call ``callback`` every ``period`` s, the first time one period after start."""
        if not period > 0:
            raise ConfigError(f'period {period!r}: must be > 0 s')
        self._tasks.append([0.0, float(period), callback, -_ERROR_LOG_EVERY])

    def start(self) -> None:
        """Start the thread (no-op when running)."""
        if self._thread is not None:
            return
        now = time.monotonic()
        for task in self._tasks:
            task[0] = now + task[1]
        self._stopping = False
        self._wake = threading.Lock()
        self._wake.acquire()
        self._thread = threading.Thread(target=self._run, args=(self._wake,), name=self.name,
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop and join the thread (idempotent); a running callback finishes first."""
        self._stopping = True
        try:
            self._wake.release()
        except RuntimeError:  # not held: never started, or stopped before
            pass
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self._thread = None

    def _run(self, wake: threading.Lock) -> None:
        while self._tasks:
            due = min(task[0] for task in self._tasks)
            if wake.acquire(timeout=max(0.0, due - time.monotonic())) or self._stopping:
                return
            now = time.monotonic()
            for task in self._tasks:
                if task[0] <= now:
                    # Next slot on the grid; after a stall skip the missed ones, not catch up.
                    task[0] += task[1] * max(1, int((now - task[0]) // task[1]) + 1)
                    self._call(task, now)

    def _call(self, task: list, now: float) -> None:
        try:
            task[2]()
        except Exception as exc:  # a failing task must not end the others
            if now - task[3] >= _ERROR_LOG_EVERY:
                task[3] = now
                self._log.error('%s: %s failed: %s: %s', self.name,
                                getattr(task[2], '__name__', task[2]), type(exc).__name__, exc)
