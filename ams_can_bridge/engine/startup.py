# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The bridge's start-up decisions without ROS: the bus settings, the errors, the summary.

The node (``ros/bridge_node.py``) declares the parameters and logs; which values stop the
bridge, in which words, all of them at once, and what the start summary says are decided
here and tested without rclpy (test_engine_startup.py). The unknown keys and their nearest names
are ``device_set.unknown_parameter_errors``; the device set and its overlaps ``DeviceSet``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import logging
from typing import Any, Callable, Mapping

from ams_can_bridge.can_io import BusConfig, parse_options
from ams_can_bridge.device_set import format_ids
from ams_can_bridge.devices.base import Device
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.parameters import raise_param_errors

NO_DEVICES_WARNING = (
    'devices is empty: the bridge decodes nothing and publishes only the CAN bus '
    'status. Set devices to your instances in the params file (e.g. devices: '
    '[ams, ivt_s], see config/*.yaml) or --ros-args -p "devices:=[bms16]"')


@dataclass
class BusSettings:
    """The can.* values as the bus layer takes them, and what is wrong with them."""

    config: BusConfig | None  # None: a value that can never work (errors says which)
    interface: str
    hardware_id: str  # '<interface>:<channel>', the diagnostics' hardware_id
    replay_clock: bool
    errors: list[str] = field(default_factory=list)  # stop the bridge, with every other
    replay_exit: bool = False  # end the process once the replay has finished
    warnings: list[str] = field(default_factory=list)  # logged, the bridge starts

    @property
    def replaying(self) -> bool:
        """Tell whether the bus is a replayed log (stamps without a frame follow it)."""
        return self.interface == 'replay'


def bus_settings(bus: Mapping[str, Any]) -> BusSettings:
    """
    Turn the declared can.* values into a BusConfig; collect, never raise, what cannot work.

    A bus setting that cannot work is collected: the devices are still declared after it,
    so that every problem of the params file is reported at once. What can never work
    (``BusConfig.check``) stops the bridge rather than being retried forever.
    """
    settings = BusSettings(None, bus['interface'], f"{bus['interface']}:{bus['channel']}",
                           replay_clock=bus['replay_clock'],
                           replay_exit=bool(bus.get('replay_exit')))
    if settings.replay_exit and not settings.replaying:
        settings.errors.append(f'can.replay_exit is true but can.interface is '
                               f"{bus['interface']!r}: only a replayed log ends (set "
                               "can.interface to 'replay', or replay_exit to false)")
    try:
        options = parse_options(bus['options'])
    except ValueError as exc:
        settings.errors.append(f'can.options: {exc} (write each option as key=value)')
        return settings
    try:
        config = BusConfig(
            interface=bus['interface'], channel=bus['channel'], bitrate=bus['bitrate'],
            fd=bus['fd'], options=options, reconnect_period=bus['reconnect_period'],
            replay_rate=bus['replay_rate'], record=bus['record'],
            use_bus_time=bus['use_bus_time'], slcan_bulk_read=bus['slcan_bulk_read'])
        settings.config = config
        settings.warnings = config.check()
    except ValueError as exc:
        settings.errors.append(str(exc))
    return settings


def launch_gate(hardware_id: str, node: Mapping[str, Any], bus: Mapping[str, Any], *,
                autostart: bool | None, logger: logging.Logger,
                node_name: str) -> tuple[CommandGate, bool, str | None]:
    """
    Return the transmit gate as launched, whether activate arms it later, and a refusal.

    ``commands_enabled: true`` given at launch arms the gate at once with ``autostart``;
    without it the bridge is configured, not active, so nothing may be sent yet: activate
    arms it as given (the node sets the parameter false meanwhile). The refusal (enabled
    without ``commands_allowed``) is one of the start errors.
    """
    gate = CommandGate(hardware_id, allowed=node['commands_allowed'],
                       connect_wait=bus['connect_wait'], logger=logger, node_name=node_name)
    enabled = bool(node['commands_enabled'])
    later = enabled and not autostart and gate.allowed
    return gate, later, gate.start_enabled(enabled and not later)


def check_replay_clock(settings: BusSettings) -> None:
    """Raise ConfigError when /clock is asked of a bus that is no replayed log."""
    if settings.replay_clock and not settings.replaying:
        raise ConfigError('can.replay_clock is true but can.interface is '
                          f'{settings.interface!r}: '
                          '/clock comes from a replayed log only '
                          "(set can.interface to 'replay', or replay_clock to false)")


def start_error(errors: list[str], exc: ConfigError) -> ConfigError:
    """
    Return the one ConfigError a failed start raises: every value the user wrote first.

    ``errors``: the unusable values collected while declaring (unknown keys included);
    ``exc``: what stopped the configuration. It is added to the list unless it is that list
    already (``raise_param_errors``) or one of its entries (the same key).
    """
    if errors:
        text = str(exc)
        aggregate = all(e in text for e in errors)  # raise_param_errors() itself
        if not aggregate and not any(text.startswith(e.split(' ', 1)[0]) for e in errors):
            errors = [*errors, text]
        try:
            raise_param_errors(errors)
        except ParamError as every:
            exc = every
    return ConfigError(str(exc))


def run_start_checks(configure: Callable[[], None], errors: list[str],
                     unknown: Callable[[], list[str]]) -> None:
    """
    Run ``configure``; raise one ConfigError naming every problem of the start values.

    ``errors`` is the list ``configure`` collects unusable values into (emptied on a
    failure: a later configure judges the values afresh); ``unknown`` returns the keys
    given that nothing declared, asked even when ``configure`` stopped early.
    """
    try:
        try:
            configure()
        finally:  # a typo in a key is reported with the other problems, all at once
            errors += unknown()
        raise_param_errors(errors)
    except ConfigError as exc:  # ParamError included
        error = start_error(errors, exc)
        errors.clear()
        raise error from None


def security_warning(allowed: bool, environ: Mapping[str, str]) -> str | None:
    """
    Return the start-up WARN for ``commands_allowed: true`` without enforced SROS2, or None.

    The gate is no access control: without DDS security every participant on the domain
    may set ``commands_enabled`` and call the command services. Enforced means rcl's own
    switches: ROS_SECURITY_ENABLE=true and ROS_SECURITY_STRATEGY=Enforce (rcl then refuses
    to start a participant without the keys of its enclave).
    """
    if not allowed:
        return None
    enable = environ.get('ROS_SECURITY_ENABLE', '')
    strategy = environ.get('ROS_SECURITY_STRATEGY', '')
    if enable == 'true' and strategy == 'Enforce':
        return None
    return (f'commands_allowed is true and ROS 2 security is not enforced (ROS_SECURITY_ENABLE='
            f'{enable or "unset"}, ROS_SECURITY_STRATEGY={strategy or "unset"}): any node on '
            f'ROS_DOMAIN_ID {environ.get("ROS_DOMAIN_ID") or "0"} can set commands_enabled and '
            'command the bridge. Run it with SROS2: ROS_SECURITY_ENABLE=true, '
            'ROS_SECURITY_STRATEGY=Enforce, --enclave /ams_can_bridge and security/policy.xml '
            '(doc/sros2.md)')


def start_summary(config: BusConfig, hardware_id: str, devices: Mapping[str, Device], *,
                  enabled: bool, allowed: bool) -> tuple[str, str | None]:
    """Return the start-up log: the INFO text, and the WARN text (no device; a device's)."""
    rate = f' @ {config.bitrate} bit/s' if config.bitrate else ''
    lines = [f'CAN bus {hardware_id}{rate}'
             + (' (FD)' if config.fd else '')
             + (f', recording to {config.record}' if config.record else '')
             + (', commands ENABLED (commands_enabled set at launch)'
                if enabled else ', listen only')
             + ('' if allowed else
                ' (commands_allowed is false: commands cannot be enabled)')]
    warnings = []
    for name, device in devices.items():
        # 'IDs 0x300-0x301; 0x18FF50E5 (29-bit)' without its first word
        ids = format_ids(device.frame_ids).partition(' ')[2]
        lines.append(f'  {name} ({device.TYPE}): {ids}')
        info, warn = device.start_log()  # a dbc device: how each field is computed
        lines += [f'    {line}' for line in info]
        warnings += [f'{name}: {line}' for line in warn]
    if not devices:
        lines.append('  no devices configured (set the devices parameter)')
        return '\n'.join(lines), NO_DEVICES_WARNING
    return '\n'.join(lines), '\n'.join(warnings) or None


def name_collision(graph: list[tuple[str, str]], name: str, namespace: str) -> str | None:
    """
    Return the warning when another node of the graph has this node's name and namespace.

    ``graph``: (name, namespace) of every node discovered, this one included. Two bridges
    with one name mix their parameters and services, and their /diagnostics statuses are
    indistinguishable ('ams_can_bridge: CAN bus' from both).
    """
    if graph.count((name, namespace)) < 2:
        return None
    full = namespace.rstrip('/') + '/' + name
    return (f'another node is named {full} on this ROS graph: two bridges of one name mix '
            'their parameters and services, and their /diagnostics statuses '
            f"('{full.lstrip('/')}: CAN bus', ...) cannot be told apart. Give each bridge a "
            'name or a namespace of its own: --ros-args -r __node:=bridge_can1, or -r '
            '__ns:=/car2 (bridge.launch.py namespace:=car2)')
