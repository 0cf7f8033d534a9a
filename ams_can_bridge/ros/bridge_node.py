# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``bridge`` node: the ROS adapter of the engine, its parameters and its services.

A thin rclpy LifecycleNode: every decision is made in ``engine/``, without ROS
(doc/architecture.md, "Layout"). Here: the lifecycle, the parameter declarations
(``ros/params.py``), the publishers (``ros/sink.py``) and one service per command row
(``ros/services.py``), in ``service_group`` (a call may wait).
"""
from __future__ import annotations

import logging
import os
import time
import traceback
from typing import Any, Callable

from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter

from ams_can_bridge import realtime
from ams_can_bridge.can_io import CanIo
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.base import Device
from ams_can_bridge.engine.commands import Commands
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.engine.live import device_clock, live_engine, open_bus, settle_heap
from ams_can_bridge.engine.param_sets import apply_set, not_set_refusal, set_refusal
from ams_can_bridge.engine.startup import (bus_settings, check_replay_clock, launch_gate,
                                           run_start_checks, security_warning, start_summary)
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.parameters import AUTOSTART, BUS_PARAMS, NODE_PARAMS
from ams_can_bridge.ros.bus_log import BusStateLog
from ams_can_bridge.ros.call_group import CommandGroup
from ams_can_bridge.ros.convert import ContextLog, stdlib_logger
from ams_can_bridge.ros.overrides import unapplied_overrides
from ams_can_bridge.ros.params import ParamRegistry
from ams_can_bridge.ros.requests import guard_services
from ams_can_bridge.ros.services import offer_services, parameter_setter
from ams_can_bridge.ros.sink import RosSink

NODE_NAME = 'ams_can_bridge'
REPLAY_EXIT_ACK_WAIT = 1.0  # s the publishers wait for their subscribers' acks before an exit
# s a transition waits for the calls it ended to answer (they end within tens of ms; a
# device's own bound, ivt_s.command_timeout and the like, is the worst case)
CALLS_END_WAIT = 5.0

__all__ = ['BridgeNode', 'ConfigError', 'NODE_NAME']


class BridgeNode(LifecycleNode):
    """Bridge battery-management CAN devices to ROS topics and diagnostics."""

    def __init__(self, node_name: str = NODE_NAME, *, argv: list[str] | None = None,
                 on_exit: Callable[[str], None] | None = None, **kwargs: Any) -> None:
        """
        Declare, configure and activate (autostart); the executable passes two more.

        ``argv``: the command line rclpy was started with, whose ``-p`` values are checked
        against those the node received; ``on_exit(reason)`` asks the process to end
        (``can.replay_exit``).
        """
        super().__init__(node_name, **kwargs)
        self._argv = argv
        self._on_exit = on_exit
        guard_services(self)  # parameter and lifecycle services: a bad request is answered
        self.params = ParamRegistry(self)
        self.service_group = CommandGroup()  # never every executor thread (call_group.py)
        self.devices: dict[str, Device] = {}
        self.commands: Commands | None = None  # made in _configure (the devices' commands)
        self.command_services: dict[str, list[Any]] = {}  # {instance: its command services}
        self.gate: CommandGate | None = None  # made in _configure (the bus parameters)
        self.can_io: CanIo | None = None
        self.sink: RosSink | None = None  # made in _configure (the devices' topics)
        self._ready = False
        self._active = False
        self._armed_at_launch = False  # commands_enabled: true given at launch, not autostart
        # configure and activate as one step: only in the constructor (autostart); a later
        # configure through change_state leaves the bridge inactive, whatever autostart says
        self._autostarting = False
        self._start_error: ConfigError | None = None
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self.autostart = self.params.declare('autostart', AUTOSTART)
        if self.autostart is not False:  # unusable (None): configured, and its error named
            self._autostarting = True
            try:
                configured = self.trigger_configure()
            finally:
                self._autostarting = False
            if configured != TransitionCallbackReturn.SUCCESS:
                error = self._start_error or ConfigError('the bridge could not be configured')
                self.destroy_node()
                raise error
            self.trigger_activate()

    @property
    def commands_enabled(self) -> bool:
        """Tell whether commands are enabled now (the gate's)."""
        return self.gate is not None and self.gate.enabled

    @property
    def commands_allowed(self) -> bool:
        """Tell whether commands may be enabled at all (the gate's, set at launch)."""
        return self.gate is not None and self.gate.allowed

    # --- lifecycle --------------------------------------------------------------------------
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Check every parameter, build the devices and the engine, open the bus."""
        try:
            self._setup()
        except ConfigError as exc:
            self._start_error = exc
            self._release()
            if not self.autostart:  # autostart: the constructor raises it (exit 2)
                self.get_logger().error(f'cannot configure: {exc}')
            return TransitionCallbackReturn.FAILURE
        except Exception:  # a bug, not a setting: named with its traceback
            self.get_logger().error(f'configure failed:\n{traceback.format_exc()}')
            self._release()
            raise
        self._start_error = None
        settle_heap()  # before any sender runs: no full collection of all this while armed
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Publish (telemetry, stale messages, diagnostics); commands follow the gate."""
        if self.sink is not None:  # made by the configure this transition follows
            self.sink.enabled = True
        self._active = True
        self.periodic.start()
        if self._armed_at_launch:  # commands_enabled: true at launch applies when active
            self._armed_at_launch = False
            self.set_parameters([Parameter('commands_enabled', value=True)])
        return TransitionCallbackReturn.SUCCESS

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Become a pure listener: calls ended, commands off (nothing sent), nothing published."""
        self._active = False
        ended = self._cancel_calls('deactivate')
        if self.commands_enabled:
            self.set_parameters([Parameter('commands_enabled', value=False)])
        if self.gate is not None:  # whatever became of that set: nothing is sent now
            self.gate.set_enabled(False, how='the bridge was deactivated')
        self._wait_calls(ended, 'deactivate')
        self.periodic.stop()
        if self.sink is not None:
            self.sink.enabled = False
        self.get_logger().info('inactive: decoding, publishing nothing, sending nothing')
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release everything configure built: bus closed, threads joined, services gone."""
        self._release('cleanup')
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release everything, from whichever state."""
        self._release('shutdown')
        return TransitionCallbackReturn.SUCCESS

    def _cancel_calls(self, transition: str) -> int:
        """End the command calls in flight (answered 'cancelled by <transition>')."""
        return self.commands.pipeline.cancel_calls(transition) if self.commands else 0

    def _wait_calls(self, ended: int, transition: str) -> None:
        """Wait until the ended calls have returned and their answers are sent (bounded)."""
        calls_done = self.commands is None or self.commands.pipeline.wait_calls(CALLS_END_WAIT)
        # rclpy sends an answer after its callback returned: the group counts it until then
        answered = self.service_group.wait_idle(CALLS_END_WAIT)
        if not (calls_done and answered):
            self.get_logger().error(f'{transition}: calls still running after '
                                    f'{CALLS_END_WAIT:g} s')
        elif ended:
            self.get_logger().info(f'{transition}: {ended} call(s) in flight ended first')

    def _setup(self) -> None:
        """Configure (raise ConfigError naming every bad value), then open the bus."""
        run_start_checks(self._configure, self.params.errors, self.params.unknown)
        self._ready = True
        assert self.can_io is not None  # opened by _configure above
        if self._autostarting and self.sink is not None:
            # configure and activate are one step here: a frame that arrives between them
            # (a replay plays at once) is published, not lost to the inactive state
            self.sink.enabled = True
        self.can_io.start()
        summary, warning = start_summary(self.bus_config, self.hardware_id, self.devices,
                                         enabled=self.commands_enabled,
                                         allowed=self.commands_allowed)
        self.get_logger().info(summary)
        for text in (warning, security_warning(self.commands_allowed, os.environ)):
            if text:
                self.get_logger().warning(text)

    def _release(self, transition: str = 'shutdown') -> None:
        """
        End the calls in flight; stop the periodic work, the senders and the bus thread.

        The services are destroyed only once their callbacks have returned (and rclpy has
        sent their answers): a service destroyed under a running callback ends the executor.
        """
        self._ready = self._active = False
        ended = self._cancel_calls(transition)
        if getattr(self, 'periodic', None) is not None:
            self.periodic.stop()
        if self.gate is not None:
            self.gate.attach_bus(None)  # a command from now on is answered 'shutting down'
        if self.commands is not None:
            self.commands.close()
            self._wait_calls(ended, transition)
            self.commands = None
        for services in self.command_services.values():
            for service in services:
                self.destroy_service(service)
        self.command_services = {}
        if self.can_io is not None:
            self.can_io.stop()
            self.can_io = None
        sink = getattr(self, 'sink', None)
        if sink is not None:
            sink.enabled = False
            for publisher in sink.publishers():
                self.destroy_publisher(publisher)
            self.sink = None

    # --- configure: parameters declared, the pieces built ---------------------------------
    def _configure(self) -> None:
        if self._argv is not None:  # a -p rcl dropped in favour of the params file's value
            self.params.errors += unapplied_overrides(
                self._argv, self.get_fully_qualified_name(),
                {name: p.value for name, p in self._parameter_overrides.items()})
        bus = self.params.declare_all('can.', BUS_PARAMS)
        node = self.params.declare_all('', NODE_PARAMS)
        self.diagnostics_period = node['diagnostics_period']
        problem = realtime.use(node['realtime_priority'])
        if problem:
            self.get_logger().warning(problem)
        elif node['realtime_priority']:
            self.get_logger().info(f"the bridge's own senders run at SCHED_FIFO priority "
                                   f"{node['realtime_priority']} (realtime_priority)")
        settings = bus_settings(bus)  # collected: every problem of the file at once
        self.params.errors += settings.errors
        # a can.* value that is unusable was replaced by its default: warnings about that
        # default ('can.bitrate is 0 with slcan' for '500k') would contradict the error
        if not any(error.startswith('can.') for error in self.params.errors):
            for warning in settings.warnings:
                self.get_logger().warning(warning)
        if settings.config is not None:
            self.bus_config = settings.config
        self.hardware_id = settings.hardware_id
        self.gate, later, refused = launch_gate(
            self.hardware_id, node, bus, autostart=self._autostarting,
            logger=self._stdlib_logger('gate', logging.DEBUG),
            node_name=self.get_fully_qualified_name())
        if later:  # configured, not active: nothing may be sent; activate arms it as given
            self._armed_at_launch = True
            self.set_parameters([Parameter('commands_enabled', value=False)])
        if refused:
            self.params.errors.append(refused)
        bus_log = BusStateLog(self.get_logger(), self.hardware_id, bus['channel'],
                              bus['reconnect_period'])
        check_replay_clock(settings)
        # the devices' clock is the bus's: arrival moments, a replay's log time (live.py)
        self.device_set = DeviceSet(node['devices'], self.params.declare,
                                    clock=device_clock(lambda: self.can_io))
        self.devices = self.device_set.devices
        if self.params.errors:
            return  # the node will not start (raise_errors): no bus, no publishers
        self.sink = RosSink(self, {name: list(device.extra_arrays())
                                   for name, device in self.devices.items()},
                            self.hardware_id, settings.replay_clock,
                            alive=lambda: self._ready and self.context.ok(),
                            figures={name: device.FIGURES
                                     for name, device in self.devices.items()})
        self.engine, self.bus_view, self.periodic = live_engine(
            self.device_set, self.sink, settings, self.gate, lambda: self.can_io,
            status_prefix=self.status_prefix(), diagnostics_period=self.diagnostics_period,
            on_bus_status=bus_log.update, logger=self._stdlib_logger,
            thread_name=f'{NODE_NAME}-periodic',
            on_replay_end=self._replay_ended if settings.replay_exit else None)
        # after Ctrl-C the logger may be gone with the context: the senders' last lines
        # (stopped) are then dropped
        self.commands = Commands(self.gate, self.devices, ContextLog(self.get_logger(), self),
                                 set_config=parameter_setter(self))
        self.command_services = offer_services(self, self.commands, self.service_group)
        self.can_io = open_bus(self.bus_config, self.engine, self.device_set, self.gate,
                               self._stdlib_logger('can_io'))

    def _replay_ended(self) -> None:
        """can.replay_exit: let the last messages reach their subscribers, then end."""
        deadline = time.monotonic() + REPLAY_EXIT_ACK_WAIT  # for all of them together
        for publisher in self.sink.publishers() if self.sink is not None else ():
            left = max(0.0, deadline - time.monotonic())
            publisher.wait_for_all_acked(Duration(seconds=left))
        reason = 'the replay has finished (can.replay_exit)'
        if self._on_exit is None:
            self.get_logger().info(f'{reason}: nothing to end (no process owns this node)')
        else:
            self._on_exit(reason)

    def _stdlib_logger(self, part: str, level: int = logging.NOTSET) -> logging.Logger:
        """Return a stdlib logger of this node whose records go to the node's rclpy logger."""
        return stdlib_logger(f'{NODE_NAME}.{part}.{id(self)}', self.get_logger(), level)

    def publish_diagnostics(self) -> None:
        """Publish one DiagnosticArray now: every device plus the CAN bus."""
        self.engine.publish_diagnostics()

    def status_prefix(self) -> str:
        """Return what the status names start with: 'car2/ams_can_bridge' (namespaced)."""
        # /diagnostics is global: two bridges in car1 and car2 must not both say
        # 'ams_can_bridge: ams'; without a namespace this is the plain node name
        return self.get_fully_qualified_name().lstrip('/')

    # --- services and parameters ------------------------------------------------------------
    def set_parameters(self, parameter_list: list[Parameter]) -> list[SetParametersResult]:
        """Set each parameter on its own (as rclpy does), NOT_SET refused (see below)."""
        return [self.set_parameters_atomically([param]) for param in parameter_list]

    def set_parameters_atomically(self, parameter_list: list[Parameter]) -> SetParametersResult:
        """Set all or none; PARAMETER_NOT_SET for a declared parameter is refused, logged."""
        # rclpy would undeclare it (its value gone until a restart, ams.bank_count included);
        # refused here, before rclpy's own checks, so every parameter is refused alike
        for param in parameter_list:
            if param.type_ == Parameter.Type.NOT_SET and self.has_parameter(param.name):
                reason = not_set_refusal(param.name)
                self.get_logger().warning(f'refused: {reason}')
                return SetParametersResult(successful=False, reason=reason)
        return super().set_parameters_atomically(parameter_list)

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        try:
            return self._judge_set(parameters)
        except Exception as exc:  # a bug: the set is refused, the executor goes on
            self.get_logger().error(f'parameter set refused, internal error:\n'
                                    f'{traceback.format_exc()}')
            return SetParametersResult(successful=False,
                                       reason=f'internal error: {type(exc).__name__}: {exc}')

    def _judge_set(self, parameters: list[Parameter]) -> SetParametersResult:
        for param in parameters:
            reason = self.params.validate(param)
            # has_parameter is false while a parameter is being declared: a set is judged
            if reason is None and self.has_parameter(param.name):
                reason = set_refusal(param.name, self.params.value(param), gate=self.gate,
                                     devices=self.devices if self._ready else {},
                                     active=self._active, configured=self._ready,
                                     log=self.get_logger())
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, parameters: list[Parameter]) -> None:
        if self._ready and self.gate is not None:
            try:
                apply_set({p.name: self.params.value(p) for p in parameters}, gate=self.gate,
                          devices=self.devices, log=self.get_logger())
            except Exception:  # a bug: logged; the set stands, the executor goes on
                self.get_logger().error(f'parameter set not applied, internal error:\n'
                                        f'{traceback.format_exc()}')

    def destroy_node(self) -> None:
        """Release everything (as on_shutdown) and destroy the node."""
        self._release()
        super().destroy_node()
        # rclpy (Jazzy) leaves the lifecycle state machine alive, and with it the node's
        # handle and its DDS participant (11 file descriptors per node, never freed)
        self._state_machine.destroy_when_not_in_use()
