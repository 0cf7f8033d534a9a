"""
The ``bridge`` node: the ROS adapter of the engine, its parameters and its services.

Data: the CanIo receive thread hands every frame to the ``Engine``, which decodes it into
the devices and, on a primary status frame, emits that device's BatteryState and arrays into
the node's ``RosSink`` (``ros/sink.py``) on the same thread (rclpy publishers are
thread-safe). So every primary frame becomes exactly one message with the values of that
moment, a replay at rate 0 is paced by publishing (nothing queued, nothing lost), and the
executor is not woken per frame: profiles showed the executor's wake-up (rebuilding its wait
set) costing more than the decoding itself. The executor runs only the services: the
engine's periodic work (diagnostics, stale messages, the watch that notices state and level
changes) runs on a thread of its own (``Periodic``), so an idle bridge wakes no executor at
all. Services that wait go in ``service_group`` (reentrant), and telemetry keeps flowing
while a command waits for the device.

COMMANDERS seam (the command services live in other modules). For each device instance
whose type is in ``ams_can_bridge.registry.COMMANDERS`` the node builds ``cls(gate, device,
name, node)``; the parameters its services use are the device type's ``COMMAND_PARAMS``,
declared with the device (``DeviceSet``). Every frame goes through the gate
(``engine/gate.py``, ``CommandGate``): commands_allowed / commands_enabled, the bus wait, the
send locks and the command log line are the gate's; the node only forwards the
``commands_enabled`` parameter to ``gate.set_enabled`` and names the service a thread answers
(``gate.calling``). The node is the commander's ``ServiceHost`` (``ros/commander.py``):
``create_service`` / ``destroy_service``, ``service_group``, ``get_logger``. The gate calls
a commander's ``on_commands_enabled(enabled)`` (a listener) when ``commands_enabled``
changes; the node calls its ``destroy()`` at shutdown.
A device's parameters ``<name>.<key>`` belong to the device: the node asks the device
(``config_reason``) before a set and applies an accepted set to it (``configure``: a new
frozen configuration swapped in whole); commanders read ``device.config`` when called.
"""
from __future__ import annotations

import logging
import math
import time
import traceback
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.parameter import Parameter

from ams_can_bridge import registry
from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.can_io import BusConfig, CanIo, parse_options
from ams_can_bridge.can_io.core import STATE_CHANGE_FORMAT
from ams_can_bridge.device_set import DeviceSet, unknown_parameter_errors
from ams_can_bridge.devices.base import Device
from ams_can_bridge.engine.core import Engine
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.parameters import AUTOSTART, BUS_PARAMS, NODE_PARAMS
from ams_can_bridge.periodic import Periodic
from ams_can_bridge.ros.bus_log import BusStateLog
from ams_can_bridge.ros.commander import Commander
from ams_can_bridge.ros.convert import format_ids, RosLogHandler
from ams_can_bridge.ros.params import ParamRegistry
from ams_can_bridge.ros.sink import RosSink

NODE_NAME = 'ams_can_bridge'
CLOCK_PERIOD = 0.01  # s between /clock messages of a replay (can.replay_clock)

__all__ = ['BridgeNode', 'ConfigError', 'NODE_NAME']


class BridgeNode(LifecycleNode):
    """Bridge battery-management CAN devices to ROS topics and diagnostics."""

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.params = ParamRegistry(self)
        self.service_group = ReentrantCallbackGroup()
        self.devices: dict[str, Device] = {}
        self.commanders: dict[str, Commander] = {}
        self.gate: CommandGate | None = None  # made in _configure (the bus parameters)
        self.can_io: CanIo | None = None
        self.sink: RosSink | None = None  # made in _configure (the devices' topics)
        self._ready = False
        self._replaying = False
        self._active = False
        self._armed_at_launch = False  # commands_enabled: true given at launch, not autostart
        self._start_error: ConfigError | None = None
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
        self.autostart = self.params.declare('autostart', AUTOSTART)
        if self.autostart is not False:  # unusable (None): configured, and its error named
            if self.trigger_configure() != TransitionCallbackReturn.SUCCESS:
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
        """Become a pure listener: commands off (nothing is sent), nothing published."""
        self._active = False
        if self.commands_enabled:
            self.set_parameters([Parameter('commands_enabled', value=False)])
        self.periodic.stop()
        if self.sink is not None:
            self.sink.enabled = False
        self.get_logger().info('inactive: decoding, publishing nothing, sending nothing')
        return TransitionCallbackReturn.SUCCESS

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release everything configure built: bus closed, threads joined, services gone."""
        self._release()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Release everything, from whichever state."""
        self._active = False
        self._release()
        return TransitionCallbackReturn.SUCCESS

    def _setup(self) -> None:
        """Configure (raise ConfigError naming every bad value), then open the bus."""
        try:
            try:
                self._configure()
            finally:  # a typo in a key is reported with the other problems, all at once
                self.params.errors += self._unknown_parameters()
            self.params.raise_errors()
        except (ParamError, ConfigError) as exc:
            if self.params.errors:  # the values the user wrote come first, all of them
                text = str(exc)
                aggregate = all(e in text for e in self.params.errors)  # raise_errors() itself
                if not aggregate and not any(text.startswith(e.split(' ', 1)[0])
                                             for e in self.params.errors):
                    self.params.errors.append(text)
                try:
                    self.params.raise_errors()
                except ParamError as every:
                    exc = every
            self.params.errors = []  # a later configure judges the values afresh
            raise ConfigError(str(exc)) from None
        self._ready = True
        assert self.can_io is not None  # opened by _configure above
        if self.autostart and self.sink is not None:
            # configure and activate are one step here: a frame that arrives between them
            # (a replay plays at once) is published, not lost to the inactive state
            self.sink.enabled = True
        self.can_io.start()
        self._log_summary()

    def _release(self) -> None:
        """Stop the periodic work, the commanders and the bus thread; drop the publishers."""
        self._ready = False
        self._active = False
        periodic = getattr(self, 'periodic', None)
        if periodic is not None:
            periodic.stop()
        if self.gate is not None:
            self.gate.attach_bus(None)  # a command from now on is answered 'shutting down'
        for commander in self.commanders.values():
            commander.destroy()
        self.commanders.clear()
        if self.can_io is not None:
            self.can_io.stop()
            self.can_io = None
        sink = getattr(self, 'sink', None)
        if sink is not None:
            sink.enabled = False
            for publisher in sink.publishers():
                self.destroy_publisher(publisher)
            self.sink = None

    # --- set-up ---------------------------------------------------------------------------
    def _unknown_parameters(self) -> list[str]:
        """Every key given for this node (file sections, -p) that nothing declared."""
        given = {name: param.value for name, param in self._parameter_overrides.items()}
        return unknown_parameter_errors(given, self._parameters.keys())

    def _configure(self) -> None:
        bus = self.params.declare_all('can.', BUS_PARAMS)
        node = self.params.declare_all('', NODE_PARAMS)
        self.diagnostics_period = node['diagnostics_period']
        # A bus setting that cannot work is collected, not raised: the devices are still
        # declared, so that every problem of the params file is reported at once.
        try:
            options = parse_options(bus['options'])
        except ValueError as exc:
            self.params.errors.append(f'can.options: {exc} (write each option as key=value)')
        else:
            try:
                self.bus_config = BusConfig(
                    interface=bus['interface'], channel=bus['channel'], bitrate=bus['bitrate'],
                    fd=bus['fd'], options=options, reconnect_period=bus['reconnect_period'],
                    replay_rate=bus['replay_rate'], record=bus['record'],
                    use_bus_time=bus['use_bus_time'], slcan_bulk_read=bus['slcan_bulk_read'])
                # what can never work stops the bridge here rather than being retried forever
                for warning in self.bus_config.check():
                    self.get_logger().warning(warning)
            except ValueError as exc:
                self.params.errors.append(str(exc))
        self.hardware_id = f"{bus['interface']}:{bus['channel']}"
        gate_logger = self._stdlib_logger('gate')
        gate_logger.setLevel(logging.DEBUG)  # the rclpy logger decides what is shown
        self.gate = CommandGate(self.hardware_id, allowed=node['commands_allowed'],
                                connect_wait=bus['connect_wait'], logger=gate_logger,
                                node_name=self.get_fully_qualified_name())
        enabled = node['commands_enabled']
        if enabled and not self.autostart and self.gate.allowed:
            # configured, not active: nothing may be sent; activate arms it as given
            enabled = False
            self._armed_at_launch = True
            self.set_parameters([Parameter('commands_enabled', value=False)])
        refused = self.gate.start_enabled(enabled)
        if refused:
            self.params.errors.append(refused)
        self._bus_log = BusStateLog(self.get_logger(), self.hardware_id, bus['channel'],
                                    bus['reconnect_period'])
        self._replaying = bus['interface'] == 'replay'
        self._replay_clock = bus['replay_clock']
        if self._replay_clock and not self._replaying:
            raise ConfigError('can.replay_clock is true but can.interface is '
                              f"{bus['interface']!r}: /clock comes from a replayed log only "
                              "(set can.interface to 'replay', or replay_clock to false)")
        self.device_set = DeviceSet(node['devices'], self.params.declare)
        self.devices = self.device_set.devices
        if self.params.errors:
            return  # the node will not start (raise_errors): no bus, no publishers
        filters = self.device_set.filters
        self._make_publishers()
        for name, device in self.devices.items():
            self._add_commander(name, device)
        can_logger = self._stdlib_logger('can_io')
        # CanIo logs every state change; the node logs the user-facing transitions itself
        # (once per change, with what happens next), so only CanIo's other problems pass.
        can_logger.setLevel(logging.WARNING)
        can_logger.addFilter(lambda record: record.msg != STATE_CHANGE_FORMAT)
        self.can_io = CanIo(self.bus_config, self.engine.on_frame, filters, can_logger)
        self.gate.attach_bus(self.can_io)

    def _make_publishers(self) -> None:
        self.sink = sink = RosSink(self, {name: list(device.extra_arrays())
                                          for name, device in self.devices.items()},
                                   self.hardware_id, self._replay_clock,
                                   alive=lambda: self._ready and self.context.ok())
        self._closed_status = BusStatus(
            state=BusState.STOPPED, reason='', frames_in=0, frames_out=0, frames_dropped_tx=0,
            error_frames=0, reconnects=0, hardware_id=self.hardware_id)
        engine_logger = self._stdlib_logger('engine')
        engine_logger.setLevel(logging.DEBUG)  # the rclpy logger decides what is shown
        self.engine = Engine(
            self.device_set, sink, status_prefix=self.status_prefix(),
            interface=self.bus_config.interface, bus_status=self._bus_status, now=self._now,
            bus_values=self._bus_values, on_bus_status=self._bus_log.update,
            logger=engine_logger)
        # One thread for all periodic work (see periodic.py: why not executor timers).
        self.periodic = Periodic(f'{NODE_NAME}-periodic', self._stdlib_logger('periodic'))
        for period, call in self.engine.schedule(self.diagnostics_period):
            self.periodic.every(period, call)
        if self._replay_clock:
            self.periodic.every(CLOCK_PERIOD, self._publish_clock)

    def _stdlib_logger(self, part: str) -> logging.Logger:
        """Return a stdlib logger of this node whose records go to the node's rclpy logger."""
        logger = logging.getLogger(f'{NODE_NAME}.{part}.{id(self)}')
        logger.propagate = False
        logger.addHandler(RosLogHandler(self.get_logger()))
        return logger

    def _add_commander(self, name: str, device: Device) -> None:
        path = registry.COMMANDERS.get(device.TYPE)
        if path is None:
            return
        # every module COMMANDERS names ships with the package: a missing one is a broken
        # install, and the error says so (test_sim_runner.py::test_registry_paths_all_import)
        cls = registry.load(path)
        if not (isinstance(cls, type) and issubclass(cls, Commander)):
            raise ConfigError(f'{path} is not a Commander (ams_can_bridge.ros.commander)')
        assert self.gate is not None  # made in _configure, before the devices' commanders
        self.commanders[name] = cls(self.gate, device, name, self)

    def _log_summary(self) -> None:
        cfg = self.bus_config
        rate = f' @ {cfg.bitrate} bit/s' if cfg.bitrate else ''
        lines = [f'CAN bus {self.hardware_id}{rate}'
                 + (' (FD)' if cfg.fd else '')
                 + (f', recording to {cfg.record}' if cfg.record else '')
                 + (', commands ENABLED (commands_enabled set at launch)'
                    if self.commands_enabled else ', listen only')
                 + ('' if self.commands_allowed else
                    ' (commands_allowed is false: commands cannot be enabled)')]
        for name, device in self.devices.items():
            ids = device.frame_ids
            lines.append(f'  {name} ({device.TYPE}): ' + '; '.join(
                format_ids({i for i, e in ids if e == extended}, extended)
                for extended in (False, True) if any(e == extended for _, e in ids)))
        if not self.devices:
            lines.append('  no devices configured (set the devices parameter)')
        self.get_logger().info('\n'.join(lines))
        if not self.devices:
            self.get_logger().warning(
                'devices is empty: the bridge decodes nothing and publishes only the CAN bus '
                'status. Set devices to your instances in the params file (e.g. devices: '
                '[ams, ivt_s], see config/*.yaml) or --ros-args -p "devices:=[bms16]"')

    # --- the engine's clocks and hooks -----------------------------------------------------
    def _on_frame(self, arbitration_id: int, data: bytes, is_extended_id: bool,
                  stamp: float) -> None:
        """Hand one frame to the engine (the bus thread; bench/bench_own_path.py calls it)."""
        self.engine.on_frame(arbitration_id, data, is_extended_id, stamp)

    def publish_diagnostics(self) -> None:
        """Publish one DiagnosticArray now: every device plus the CAN bus."""
        self.engine.publish_diagnostics()

    def status_prefix(self) -> str:
        """
        Return what the diagnostics status names start with: the node's name and namespace.

        /diagnostics is global: two bridges in namespaces car1 and car2 both named
        ams_can_bridge would both say 'ams_can_bridge: ams'. The fully qualified name without
        its leading slash tells them apart ('car2/ams_can_bridge: ams'), and is the plain
        node name for a bridge without a namespace.
        """
        return self.get_fully_qualified_name().lstrip('/')

    def _now(self) -> float:
        """Return the time to stamp with when no frame gives one: a replay's log time."""
        if self._replaying and self.can_io is not None:
            stamp = self.can_io.last_stamp
            if math.isfinite(stamp):
                return stamp
        return time.time()

    def _bus_status(self) -> Any:
        can_io = self.can_io
        if can_io is None:
            return self._closed_status
        return can_io.status()

    def _bus_values(self) -> dict[str, str]:
        return {'commands_allowed': str(self.commands_allowed).lower(),
                'commands_enabled': str(self.commands_enabled).lower(),
                'commands_enabled changes': str(self.gate.changes if self.gate else 0)}

    def _publish_clock(self) -> None:
        can_io = self.can_io
        self.engine.publish_clock(can_io.last_stamp if can_io is not None else math.nan)

    # --- commands seam --------------------------------------------------------------------
    def create_service(self, srv_type: Any, srv_name: str, callback: Any,
                       **kwargs: Any) -> Any:
        """
        Create a service; a device's command service is logged (its frames and its answer).

        The call's service name is given to the gate for the thread running it, so the gate's
        command log line names it; the answer (success and message) is logged once the
        callback returns: INFO when it succeeded, WARN when not. A callback that raises is a
        bug: its traceback is logged (ERROR) and the call answered as an internal error. The
        node's parameter services pass through unchanged.
        """
        device = srv_name.split('/', 1)[0]
        if device not in getattr(self, 'devices', {}):
            return super().create_service(srv_type, srv_name, callback, **kwargs)

        def logged(request: Any, response: Any) -> Any:
            try:
                gate = self.gate
                assert gate is not None  # made in _configure, before any commander
                with gate.calling(srv_name):
                    response = callback(request, response)
            except Exception as exc:  # a bug, not a refusal: say so, keep the traceback
                self.get_logger().error(f'{srv_name}: internal error:\n'
                                        + traceback.format_exc())
                response.success = False
                response.message = (f'{srv_name}: internal error: {type(exc).__name__}: '
                                    f'{exc}; see the log')
            answer = (f'{srv_name}: answered success={response.success}: '
                      f'{response.message}')
            if response.success:
                self.get_logger().info(answer)
            else:
                self.get_logger().warning(answer)
            return response
        return super().create_service(srv_type, srv_name, logged, **kwargs)

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        for param in parameters:
            reason = self.params.validate(param)
            if (reason is None and self._ready and param.name == 'commands_enabled'
                    and param.value is True):
                assert self.gate is not None  # _ready: configured
                reason = self.gate.arming_reason(True)
                if reason:
                    self.get_logger().warning(f'refused: {reason}')
            if (reason is None and self._ready and not self._active and param.value is True
                    and param.name == 'commands_enabled'):
                reason = ('commands_enabled = true refused: the bridge is inactive (lifecycle): '
                          'activate it first (ros2 lifecycle set /ams_can_bridge activate)')
            prefix, _, key = param.name.partition('.')
            if reason is None and self._ready and prefix in self.devices and key:
                reason = self.devices[prefix].config_reason(key, self.params.value(param))
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def _after_set_parameters(self, parameters: list[Parameter]) -> None:
        if not self._ready:
            return
        changed = {p.name: self.params.value(p) for p in parameters}
        per_device: dict[str, dict[str, Any]] = {}
        for full_name, value in changed.items():
            prefix, _, key = full_name.partition('.')
            if prefix in self.devices and key:
                per_device.setdefault(prefix, {})[key] = value
        for name, changes in per_device.items():
            # one new configuration per device and set: an atomic set stays one change
            try:
                self.devices[name].configure(changes)
            except ValueError as exc:  # checked key by key before; only a combination is left
                self.get_logger().error(f'{name}: configuration change not applied: {exc}')
        if 'commands_enabled' in changed:
            # Who: ROS 2 hands the node the new value, never the caller (the parameter
            # event names this node); only SROS2 decides who may make this call at all.
            # The gate tells the commanders (its listeners) before it returns.
            assert self.gate is not None  # declared by _configure with the gate
            refused = self.gate.set_enabled(
                bool(changed['commands_enabled']),
                how='set at run time through the parameter services; the caller is not known '
                    'to the node (restrict who may set it with SROS2: security/policy.xml)')
            if refused:  # checked in _on_set_parameters: not reached
                self.get_logger().error(f'commands_enabled not applied: {refused}')

    # --- shutdown -------------------------------------------------------------------------
    def destroy_node(self) -> None:
        """Release everything (as on_shutdown) and destroy the node."""
        self._release()
        super().destroy_node()
        # rclpy (Jazzy) leaves the lifecycle state machine alive, and with it the node's
        # handle and its DDS participant (11 file descriptors per node, never freed)
        self._state_machine.destroy_when_not_in_use()
