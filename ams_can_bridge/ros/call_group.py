# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The command services' callback group: never all executor threads, and known when idle.

The executor has 4 threads (``bridge_main.EXECUTOR_THREADS``). A command call may wait for
seconds (the bus, an answer of the device), so if commands could take every thread, a
parameter set (a disarm) or a lifecycle transition would wait behind them. This
group lets at most ``COMMAND_THREADS`` command callbacks run at once: one thread
always stays for the node's own services. A further call is taken when one of them returns
(rclpy asks the group before it takes a request), and most are answered at once anyway: a
call that would wait for the bus beyond the gate's ``BUS_WAIT_SLOTS`` is refused, never
queued.

A transition that destroys the services first waits until no callback of the group runs
(``wait_idle``): rclpy answers a request after its callback returned, with the service's
handle, and a service destroyed in between ends the executor (``InvalidHandle``).
rclpy's handler calls ``ending_execution`` only after the answer was sent.
"""
from __future__ import annotations

import threading
import time
from typing import Any

from rclpy.callback_groups import CallbackGroup

# Command callbacks at once: one thread of the executor's 4 (ros/bridge_main.py's
# EXECUTOR_THREADS, which imports no rclpy for --help, so not imported here) stays free.
COMMAND_THREADS = 3


class CommandGroup(CallbackGroup):
    """Reentrant up to ``limit`` callbacks at once; ``wait_idle`` for a transition."""

    def __init__(self, limit: int = COMMAND_THREADS) -> None:
        """Allow ``limit`` command callbacks to run at once."""
        super().__init__()
        self.limit = limit
        self._cond = threading.Condition()
        self._running = 0

    @property
    def running(self) -> int:
        """Return how many callbacks of the group run now (their answers included)."""
        with self._cond:
            return self._running

    def can_execute(self, entity: Any) -> bool:
        """Tell the executor whether to take a request now (a thread is left for it)."""
        with self._cond:
            return self._running < self.limit

    def beginning_execution(self, entity: Any) -> bool:
        """Count a callback that starts; refuse it when ``limit`` run (taken later)."""
        with self._cond:
            if self._running >= self.limit:
                return False
            self._running += 1
            return True

    def ending_execution(self, entity: Any) -> None:
        """Count a callback that ended, its answer sent."""
        with self._cond:
            self._running -= 1
            self._cond.notify_all()

    def wait_idle(self, timeout: float) -> bool:
        """Wait up to timeout s until no callback of the group runs; True when none does."""
        deadline = time.monotonic() + timeout
        with self._cond:
            return self._cond.wait_for(lambda: self._running == 0,
                                       max(0.0, deadline - time.monotonic()))
