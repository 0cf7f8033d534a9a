"""
A command service call, answered and logged, without ROS.

The node wraps each device's command service in ``answered``: the gate learns which service
the thread answers (its command log line names it), the answer is logged once the callback
returns (INFO when it succeeded, WARN when not), and a callback that raises is a bug: its
traceback is logged (ERROR) and the call answered as an internal error, never as a refusal.
"""
from __future__ import annotations

import traceback
from typing import Any, Callable, Protocol

from ams_can_bridge.engine.gate import CommandGate

Callback = Callable[[Any, Any], Any]  # (request, response) -> response, as rclpy calls it


class Log(Protocol):
    """The node's logger (rclpy's, or a stdlib logger in a test)."""

    def info(self, message: str, /) -> object:
        """Log at INFO."""

    def warning(self, message: str, /) -> object:
        """Log at WARN."""

    def error(self, message: str, /) -> object:
        """Log at ERROR."""


def answered(srv_name: str, callback: Callback, gate: CommandGate, log: Log) -> Callback:
    """Return ``callback`` named to the gate, its answer logged, a raise answered."""
    def logged(request: Any, response: Any) -> Any:
        try:
            with gate.calling(srv_name):
                response = callback(request, response)
        except Exception as exc:  # a bug, not a refusal: say so, keep the traceback
            log.error(f'{srv_name}: internal error:\n' + traceback.format_exc())
            response.success = False
            response.message = (f'{srv_name}: internal error: {type(exc).__name__}: '
                                f'{exc}; see the log')
        answer = f'{srv_name}: answered success={response.success}: {response.message}'
        if response.success:
            log.info(answer)
        else:
            log.warning(answer)
        return response
    return logged
