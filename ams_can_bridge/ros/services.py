# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ROS adapter of the command side: one service per command row, answered by the pipeline.

Every device's rows (``Device.COMMANDS``, devices/commands.py) become services
``<instance>/<service>`` of their request kind (std_srvs Trigger or SetBool); a call is
handed to ``Commands.call`` (engine/commands.py), the one pipeline, which refuses, builds,
waits, sends, answers and logs. Nothing here decides anything: a new command is a builder
and a row on its device, never code in this module.
"""
from __future__ import annotations

from typing import Any, Callable, Mapping

from rclpy.node import Node
from rclpy.parameter import Parameter
from std_srvs.srv import SetBool, Trigger

from ams_can_bridge.devices.commands import Command, Request
from ams_can_bridge.engine.commands import Commands

SERVICE_TYPES: dict[Request, Any] = {Request.TRIGGER: Trigger, Request.SET_BOOL: SetBool}


def offer_services(node: Node, commands: Commands, group: Any) -> dict[str, list[Any]]:
    """Create every row's service in ``group`` (its calls may wait); {instance: services}."""
    services: dict[str, list[Any]] = {}
    for name, row in commands.rows():
        services.setdefault(name, []).append(node.create_service(
            SERVICE_TYPES[row.request], f'{name}/{row.service}', _answer(commands, name, row),
            callback_group=group))
    return services


def _answer(commands: Commands, name: str, row: Command) -> Callable[[Any, Any], Any]:
    """Return the service callback of one row: the request in, the pipeline's answer out."""
    takes_data = row.request is Request.SET_BOOL

    def callback(request: Any, response: Any) -> Any:
        data = bool(request.data) if takes_data else None
        response.success, response.message = commands.call(name, row.service, data)
        return response
    return callback


def parameter_setter(node: Node) -> Callable[[str, Mapping[str, Any]], tuple[bool, str]]:
    """Return the pipeline's port to set ``<instance>.<key>`` parameters all or none."""
    def set_config(name: str, values: Mapping[str, Any]) -> tuple[bool, str]:
        result = node.set_parameters_atomically([
            Parameter(f'{name}.{key}', value=value) for key, value in values.items()])
        return bool(result.successful), result.reason
    return set_config
