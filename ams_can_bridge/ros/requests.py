# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A bad request is answered, never fatal: the services rclpy makes for the node itself.

rclpy runs a service callback on the executor: an exception out of it ends the executor's
spin, the bridge exits 1 and an armed AMS heartbeat stops. The device command services
are answered by ``engine/commands.py``; the services rclpy creates for every node (parameters,
lifecycle, type description) are wrapped here once the node exists (``guard_services``):

- ``change_state`` with a transition the current state does not have (configure sent to
  an active bridge, an unknown id or label: rcl raises RCLError for an id) is answered
  ``success: false`` at once, with a WARN naming the state and the transitions it has;
- any other exception is logged with its traceback (ERROR) and the request answered as
  refused (``success: false``, every ``SetParametersResult`` unsuccessful with the reason).
"""
from __future__ import annotations

import traceback
from typing import Any, Callable

from rcl_interfaces.msg import SetParametersResult

Callback = Callable[[Any, Any], Any]  # (request, response) -> response, as rclpy calls it


def guard_services(node: Any) -> None:
    """Wrap every service the node has now; ``change_state`` also refuses unfit transitions."""
    log = node.get_logger()
    change_state = getattr(node, '_service_change_state', None)
    for service in node.services:
        callback = service.callback
        if service is change_state:
            callback = fitting_transition(node, callback, log)
        service.callback = guarded(service.srv_name, callback, log)


def fitting_transition(node: Any, callback: Callback, log: Any) -> Callback:
    """Answer a transition the current state does not have ``success: false``, logged."""
    def change_state(request: Any, response: Any) -> Any:
        machine = node._state_machine  # rclpy keeps it private; rcl's own list of transitions
        state = machine.current_state[1]
        available = [(t[0], t[1]) for t in machine.available_transitions]
        transition = request.transition
        fits = (any(label == transition.label for _, label in available) if transition.label
                else any(number == transition.id for number, _ in available))
        if not fits:
            asked = (f'label {transition.label!r}' if transition.label
                     else f'id {transition.id}')
            offered = ', '.join(f'{label} ({number})' for number, label in available)
            log.warning(f'change_state: transition {asked} refused: the bridge is {state}, '
                        f'whose transitions are {offered or "none"}')
            response.success = False
            return response
        return callback(request, response)
    return change_state


def guarded(name: str, callback: Callback, log: Any) -> Callback:
    """Return ``callback`` that answers a request it raises on as refused, and logs why."""
    def guard(request: Any, response: Any) -> Any:
        try:
            return callback(request, response)
        except Exception as exc:
            log.error(f'{name}: request refused, internal error:\n{traceback.format_exc()}')
            return refused(request, type(response)(),
                           f'{name}: refused: {type(exc).__name__}: {exc}')
    return guard


def refused(request: Any, response: Any, reason: str) -> Any:
    """Fill a fresh response of any of the node's own services as a refusal."""
    if hasattr(response, 'success'):  # change_state, Trigger-like
        response.success = False
    if hasattr(response, 'message'):
        response.message = reason
    if hasattr(response, 'results'):  # set_parameters: one result per parameter asked
        response.results = [SetParametersResult(successful=False, reason=reason)
                            for _ in getattr(request, 'parameters', ())]
    if hasattr(response, 'result') and isinstance(response.result, SetParametersResult):
        response.result = SetParametersResult(successful=False, reason=reason)
    return response
