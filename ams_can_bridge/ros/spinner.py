# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
An executor spun on a thread of its own, stopped without racing rclpy's shutdown.

``Executor.shutdown()`` destroys the executor's guard condition as soon as no callback runs,
and a thread still inside ``spin()`` may be about to wait on it: the thread then dies with
``AttributeError: 'NoneType' object has no attribute 'handle'`` (rclpy 7, Jazzy), seen at a
demo's and a bridge's stop on a loaded machine. So the loop here checks a stop flag between
``spin_once`` calls, ``stop()`` joins it, and only then shuts the executor down.
"""
from __future__ import annotations

import threading
import traceback
from typing import Any, Callable

# s: the longest one wait lasts when nothing wakes it. stop() wakes the executor itself,
# so this is only a fallback: each timed-out wait rebuilds rclpy's wait set over every
# service, parameter service and guard of the node (~0.9 ms of CPU for the bridge's), and at
# 10 wake-ups a second that was ~1 % of a core, idle or not (bench/README.md, issue 39).
WAKE_S = 2.0


def _nothing() -> None:
    """Do nothing: the task stop() gives the executor to end its wait."""


class Spinner:
    """Spin ``executor`` on a daemon thread named ``name`` until ``stop()``."""

    def __init__(self, executor: Any, name: str,
                 on_error: Callable[[BaseException, str], None] | None = None,
                 on_exit: Callable[[], None] | None = None) -> None:
        """
        Start spinning at once.

        on_error(exception, traceback text): a callback raised (the loop ends); on_exit(): the
        loop ended, for any reason (a stop, rclpy shut down, an error).
        """
        self.executor = executor
        self.error: BaseException | None = None
        self._on_error = on_error
        self._on_exit = on_exit
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, name=name, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException
        try:
            while not self._stop.is_set():
                self.executor.spin_once(timeout_sec=WAKE_S)
        except (ExternalShutdownException, KeyboardInterrupt):
            pass  # rclpy shut down (Ctrl-C elsewhere): the normal end
        except Exception as exc:  # a callback raised: say so, end the loop
            self.error = exc
            if self._on_error is not None:
                self._on_error(exc, traceback.format_exc())
        finally:
            if self._on_exit is not None:
                self._on_exit()

    def stop(self, timeout: float) -> bool:
        """End the loop, join it, then shut the executor down; False if either timed out."""
        self._stop.set()
        if self.thread.is_alive():
            # A task is work: the current spin_once returns with it and the loop sees the
            # flag. (executor.wake() alone is no work: rclpy waits again, for the rest of
            # the timeout.)
            self.executor.create_task(_nothing)
        self.thread.join(timeout)
        joined = not self.thread.is_alive()
        # Shutting down while the thread still waits in spin_once is the race this avoids:
        # a thread that did not end within timeout is left to the process's exit (daemon).
        done = self.executor.shutdown(timeout_sec=timeout) if joined else False
        return joined and bool(done)
