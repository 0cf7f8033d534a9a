# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Which parameter sets the running bridge allows, and what an accepted set changes: no ROS.

The node validates each value against its spec (``ros/params.py``) and then asks here:
``commands_enabled = true`` needs commands_allowed and an active bridge (lifecycle); a
device's ``<name>.<key>`` is the device's to judge (``config_reason``). An accepted set is
applied here: one new configuration per device and set (an atomic set stays one change,
``configure``), and a changed ``commands_enabled`` goes to the gate, which tells the
command side (its periodic senders) before it returns.
"""
from __future__ import annotations

from typing import Any, Mapping

from ams_can_bridge.device_set import overlap_error, overlap_problems
from ams_can_bridge.devices.base import Device
from ams_can_bridge.engine.commands import Log
from ams_can_bridge.engine.gate import CommandGate

INACTIVE_REFUSAL = ('commands_enabled = true refused: the bridge is inactive (lifecycle): '
                    'activate it first (ros2 lifecycle set /ams_can_bridge activate)')
UNCONFIGURED_REFUSAL = ('commands_enabled = true refused: the bridge is unconfigured '
                        '(lifecycle): configure and activate it first (ros2 lifecycle set '
                        '/ams_can_bridge configure, then activate)')
# Who: ROS 2 hands the node the new value, never the caller (the parameter event names
# this node); only SROS2 decides who may make this call at all.
RUN_TIME_SET = ('set at run time through the parameter services; the caller is not known '
                'to the node (restrict who may set it with SROS2: security/policy.xml)')


def set_refusal(name: str, value: Any, *, gate: CommandGate | None,
                devices: Mapping[str, Device], active: bool, log: Log,
                configured: bool = True) -> str | None:
    """
    Return why the bridge refuses ``name = value`` (a valid value), or None.

    Inactive and unconfigured alike: ``commands_enabled = true`` is refused (only activate
    arms the bridge), so a configure can never start an inactive bridge armed.
    """
    if name == 'commands_enabled' and value is True:
        reason = gate.arming_reason(True) if gate is not None else None
        if reason:
            log.warning(f'refused: {reason}')
            return reason
        if not active:
            return INACTIVE_REFUSAL if configured else UNCONFIGURED_REFUSAL
    prefix, _, key = name.partition('.')
    if prefix in devices and key:
        return devices[prefix].config_reason(key, value) or _send_overlap(
            name, value, prefix, key, devices)
    return None


def _send_overlap(name: str, value: Any, prefix: str, key: str,
                  devices: Mapping[str, Device]) -> str | None:
    """Refuse a value that makes a device send on an ID another instance uses."""
    device = devices[prefix]
    sent = device.sent_ids(device.config.replace({key: value}))
    if sent == device.sent_ids():
        return None
    problems = overlap_problems(devices, {prefix: sent})
    return f'{name} = {value!r} refused: {overlap_error(problems)}' if problems else None


def not_set_refusal(name: str) -> str:
    """Return why PARAMETER_NOT_SET is refused for a declared parameter."""
    return (f'{name} cannot be unset (PARAMETER_NOT_SET): rclpy would remove the parameter, '
            'and it could not be set again until the bridge restarts; set a value instead')


def device_changes(changed: Mapping[str, Any],
                   devices: Mapping[str, Device]) -> dict[str, dict[str, Any]]:
    """Return the changed ``<name>.<key>`` values per device instance: {name: {key: value}}."""
    per_device: dict[str, dict[str, Any]] = {}
    for full_name, value in changed.items():
        prefix, _, key = full_name.partition('.')
        if prefix in devices and key:
            per_device.setdefault(prefix, {})[key] = value
    return per_device


def apply_set(changed: Mapping[str, Any], *, gate: CommandGate,
              devices: Mapping[str, Device], log: Log) -> None:
    """Apply an accepted set of {full name: value} to the devices and the gate."""
    for name, changes in device_changes(changed, devices).items():
        # one new configuration per device and set: an atomic set stays one change
        try:
            devices[name].configure(changes)
        except ValueError as exc:  # checked key by key before; only a combination is left
            log.error(f'{name}: configuration change not applied: {exc}')
    if 'commands_enabled' in changed:
        # the gate tells the command side (its listener) before it returns
        refused = gate.set_enabled(bool(changed['commands_enabled']), how=RUN_TIME_SET)
        if refused:  # checked in set_refusal: not reached
            log.error(f'commands_enabled not applied: {refused}')
