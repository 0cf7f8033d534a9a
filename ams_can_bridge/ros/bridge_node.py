"""
The ``bridge`` node: CAN frames -> device state -> BatteryState, arrays and /diagnostics.

Threads: the CanIo receive thread decodes every frame into its devices (``handle_frame``)
and, on a primary status frame, publishes that device's BatteryState and arrays itself
(rclpy publishers are thread-safe). So every primary frame becomes exactly one message
with the values of that moment, a replay at rate 0 is paced by publishing (nothing queued,
nothing lost), and the executor is not woken per frame: profiles showed the executor's
wake-up (rebuilding its wait set) costing more than the decoding itself. The executor runs
only the services: the periodic work (diagnostics, stale messages, the watch that notices
state and level changes) runs on a thread of its own (``Periodic``), so an idle bridge
wakes no executor at all. Services that wait go in ``service_group`` (reentrant), and
telemetry keeps flowing while a command waits for the device.

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

from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rosgraph_msgs.msg import Clock
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray

from ams_can_bridge import registry, reports
from ams_can_bridge.can_io import BusConfig, CanIo, parse_options
from ams_can_bridge.can_io.core import STATE_CHANGE_FORMAT
from ams_can_bridge.device_set import DeviceSet, unknown_parameter_errors
from ams_can_bridge.devices.base import Device
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.periodic import Periodic
from ams_can_bridge.ros import convert, diag_cdr
from ams_can_bridge.ros.bus_log import BusStateLog
from ams_can_bridge.ros.commander import Commander
from ams_can_bridge.ros.convert import format_ids, RosLogHandler
from ams_can_bridge.ros.params import BUS_PARAMS, NODE_PARAMS, ParamError, ParamRegistry

NODE_NAME = 'ams_can_bridge'
MALFORMED_LOG_PERIOD = 5.0  # s between malformed-frame log lines per device
STALE_PUBLISH_PERIOD = 1.0  # s, battery_state present:false while stale
WATCH_PERIOD = 0.2  # s, how fast bus state / staleness transitions are noticed
# s: a device that keeps taking frames has its level rebuilt at most this often by the watch
# (a report costs 40-150 us; at full load every device changes every watch, and rebuilding
# all five reports 5 times a second was a third of the bridge's own CPU). A staleness change
# and the first frame after a quiet spell are still noticed at the next watch.
LEVEL_RECHECK_PERIOD = 0.5
TELEMETRY_DEPTH = 100  # history of battery_state / array publishers
CLOCK_PERIOD = 0.01  # s between /clock messages of a replay (can.replay_clock)

__all__ = ['BridgeNode', 'ConfigError', 'NODE_NAME']


class BridgeNode(Node):
    """Bridge battery-management CAN devices to ROS topics and diagnostics."""

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.params = ParamRegistry(self)
        self.service_group = ReentrantCallbackGroup()
        self.devices: dict[str, Device] = {}
        self.commanders: dict[str, Commander] = {}
        self.gate: CommandGate | None = None  # made in _configure (the bus parameters)
        self.can_io: CanIo | None = None
        self._ready = False
        self._replaying = False
        self._levels: dict[str, int] = {}
        # name -> (device revision, stale, level, monotonic time of the rebuild): a report
        # is rebuilt only after a change (see LEVEL_RECHECK_PERIOD).
        self._level_cache: dict[str, tuple[int, bool, int, float]] = {}
        # name -> (device revision, BatteryState, [(publisher, array msg)])
        self._stale_msgs: dict[str, tuple[int, Any, list]] = {}
        self._malformed_logged: dict[str, tuple[int, float]] = {}
        self._stale: dict[str, bool] = {}
        self._heard: set[str] = set()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._after_set_parameters)
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
            self.destroy_node()
            raise ConfigError(str(exc)) from None
        self._ready = True
        self.can_io.start()
        self.periodic.start()
        self._log_summary()

    @property
    def commands_enabled(self) -> bool:
        """Tell whether commands are enabled now (the gate's)."""
        return self.gate is not None and self.gate.enabled

    @property
    def commands_allowed(self) -> bool:
        """Tell whether commands may be enabled at all (the gate's, set at launch)."""
        return self.gate is not None and self.gate.allowed

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
        refused = self.gate.start_enabled(node['commands_enabled'])
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
        self._stale = {name: True for name in self.devices}
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
        self.can_io = CanIo(self.bus_config, self._on_frame, filters, can_logger)
        self.gate.attach_bus(self.can_io)

    def _make_publishers(self) -> None:
        self.battery_pubs = {}
        self.array_pubs: dict[str, dict[str, Any]] = {}
        for name, device in self.devices.items():
            self.battery_pubs[name] = self.create_publisher(
                BatteryState, f'{name}/battery_state', TELEMETRY_DEPTH)
            self.array_pubs[name] = {
                suffix: self.create_publisher(
                    Float32MultiArray, f'{name}/{suffix}', TELEMETRY_DEPTH)
                for suffix in device.extra_arrays()}
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        encoder = diag_cdr.DiagnosticsEncoder()
        self._diag_encoder = encoder if encoder.check() else None
        self._raw_telemetry = diag_cdr.check_telemetry()
        # One thread for all periodic work (see periodic.py: why not executor timers).
        self.periodic = Periodic(f'{NODE_NAME}-periodic', self._stdlib_logger('periodic'))
        self.periodic.every(self.diagnostics_period, self.publish_diagnostics)
        self.periodic.every(STALE_PUBLISH_PERIOD, self._publish_stale)
        self.periodic.every(WATCH_PERIOD, self._watch)
        if self._replay_clock:
            self.clock_pub = self.create_publisher(Clock, '/clock', 10)
            self._clock_sent = math.nan
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
            raise TypeError(f'{path} is not a Commander (ams_can_bridge.ros.commander)')
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

    # --- receive thread -------------------------------------------------------------------
    def _on_frame(self, arbitration_id: int, data: bytes, is_extended_id: bool,
                  stamp: float) -> None:
        for device in self.device_set.handle_frame(arbitration_id, data, is_extended_id,
                                                   stamp):
            self._publish_battery(device)

    # --- publishing -----------------------------------------------------------------------
    def _publish_battery(self, device: Device) -> None:
        # serialized by diag_cdr.py and published raw unless its start check failed
        self._publish_messages(device.name, *self._messages(
            device.name, device.battery_report(), raw=self._raw_telemetry))

    def _publish_stale_battery(self, name: str) -> None:
        device = self.devices[name]
        revision = device.revision
        cached = self._stale_msgs.get(name)
        if cached is None or cached[0] != revision:
            report = device.battery_report()
            # A frame may have arrived since is_stale() said so: that frame publishes
            # itself; publishing here too would give one primary frame two present messages.
            if report.present:
                return
            # Nothing in a silent device's message changes until a frame or a parameter does
            # (its revision): build it once, republish it every second (idle CPU).
            cached = (revision, *self._messages(name, report))
            self._stale_msgs[name] = cached
        # A present: false message says "nothing heard, as of now": stamped when published
        # (a replay's log time), never with the last frame's time, which would make a
        # silent device look as if its last message had just been repeated.
        cached[1].header.stamp = convert.stamp_msg(self._now())
        self._publish_messages(name, cached[1], cached[2])

    def _messages(self, name: str, report: Any,
                  raw: bool = False) -> tuple[Any, list[tuple[Any, Any]]]:
        """
        Build a device's BatteryState and its arrays' messages (with their publishers).

        raw: as CDR bytes (diag_cdr.py; rclpy's conversion of the objects was most of a
        publish), else as message objects (the stale messages, whose stamp may move).
        """
        device = self.devices[name]
        build = diag_cdr if raw else convert
        battery = build.battery_state(report, device.config.frame_id or '', self._now())
        pubs = self.array_pubs[name]
        if not pubs:
            return battery, []
        # The arrays follow their BatteryState: while it says present: false (the device
        # is silent) they are NaN, not the last values, for every array of every device.
        arrays = [(pubs[suffix], build.multi_array(
                      rows, cols, data if report.present else [math.nan] * len(data)))
                  for suffix, (rows, cols, data) in device.extra_arrays().items()
                  if suffix in pubs]
        return battery, arrays

    def _publish_messages(self, name: str, battery: Any, arrays: list[tuple[Any, Any]]) -> None:
        self._publish(self.battery_pubs[name], battery)
        for publisher, msg in arrays:
            self._publish(publisher, msg)

    def _publish(self, publisher: Any, msg: Any) -> None:
        """Publish from the receive or periodic thread; after a shutdown, drop the message."""
        try:
            publisher.publish(msg)
        except Exception:
            # Ctrl-C / SIGTERM shuts the context down under these threads before the node
            # stops them: 'context is invalid' then means "going away", not a failure.
            if self._ready and self.context.ok():
                raise

    def _publish_stale(self) -> None:
        for name, device in self.devices.items():
            if device.is_stale():
                self._publish_stale_battery(name)

    def _statuses(self) -> list[tuple[str, Any]]:
        statuses = []
        for name, device in self.devices.items():
            revision, stale = device.revision, device.is_stale()
            report = device.diagnostic_report()
            self._level_cache[name] = (revision, stale, int(report.level), time.monotonic())
            statuses.append((name, report))
        statuses.append(('CAN bus', self._bus_report()))
        return statuses

    def _device_level(self, name: str, stale: bool | None = None) -> int:
        """Return a device's diagnostic level, rebuilding its report only after a change."""
        device = self.devices[name]
        revision = device.revision
        if stale is None:
            stale = device.is_stale()
        cached = self._level_cache.get(name)
        now = time.monotonic()
        if (cached is None or cached[1] != stale
                or (cached[0] != revision and now - cached[3] >= LEVEL_RECHECK_PERIOD)):
            cached = (revision, stale, int(device.diagnostic_level()), now)
            self._level_cache[name] = cached
        return cached[2]

    def _bus_report(self) -> Any:
        status = self.can_io.status()
        malformed = sum(d.frames_malformed for d in self.devices.values())
        report = convert.bus_report(status, malformed, self.bus_config.interface)
        report.values['commands_allowed'] = str(self.commands_allowed).lower()
        report.values['commands_enabled'] = str(self.commands_enabled).lower()
        report.values['commands_enabled changes'] = str(self.gate.changes)
        return report

    def _levels_changed(self, status: Any, stale: dict[str, bool] | None = None) -> bool:
        stale = stale or {}
        levels = {name: self._device_level(name, stale.get(name)) for name in self.devices}
        levels['CAN bus'] = int(reports.bus_level(status))
        return levels != self._levels

    def publish_diagnostics(self) -> None:
        """Publish one DiagnosticArray: every device plus the CAN bus."""
        stamp = self._now()
        node = self.status_prefix()
        named = self._statuses()
        self._levels = {name: int(report.level) for name, report in named}
        statuses = [(f'{node}: {name}', report) for name, report in named]
        if self._diag_encoder is not None:  # serialized here (diag_cdr.py), published raw
            msg = self._diag_encoder.encode(stamp, statuses, self.hardware_id)
        else:
            msg = diag_cdr.diagnostic_array(stamp, statuses, self.hardware_id)
        self._publish(self.diag_pub, msg)

    def status_prefix(self) -> str:
        """
        Return what the diagnostics status names start with: the node's name and namespace.

        /diagnostics is global: two bridges in namespaces car1 and car2 both named
        ams_can_bridge would both say 'ams_can_bridge: ams'. The fully qualified name without
        its leading slash tells them apart ('car2/ams_can_bridge: ams'), and is the plain
        node name for a bridge without a namespace.
        """
        prefix = getattr(self, '_status_prefix', None)
        if prefix is None:
            prefix = self._status_prefix = self.get_fully_qualified_name().lstrip('/')
        return prefix

    def _now(self) -> float:
        """Return the time to stamp with when no frame gives one: a replay's log time."""
        if self._replaying and self.can_io is not None:
            stamp = self.can_io.last_stamp
            if math.isfinite(stamp):
                return stamp
        return time.time()

    def _publish_clock(self) -> None:
        stamp = self.can_io.last_stamp if self.can_io is not None else math.nan
        if math.isfinite(stamp) and stamp != self._clock_sent:
            self._clock_sent = stamp
            self._publish(self.clock_pub, Clock(clock=convert.stamp_msg(stamp)))

    def _watch(self) -> None:
        status = self.can_io.status()
        self._bus_log.update(status)
        now = time.monotonic()
        for name, device in self.devices.items():
            stale = device.is_stale()
            if stale != self._stale[name]:
                self._stale[name] = stale
                if stale:
                    self.get_logger().warning(
                        f'{name}: no status frame for {device.stale_timeout:g} s: STALE')
                    self._publish_stale_battery(name)
                elif name in self._heard:
                    self.get_logger().info(f'{name}: receiving again')
                else:
                    self.get_logger().info(f'{name}: first status frame received')
                self._heard.add(name)
            count = device.frames_malformed
            logged, at = self._malformed_logged.get(name, (0, -math.inf))
            if count > logged and now - at >= MALFORMED_LOG_PERIOD:
                self._malformed_logged[name] = (count, now)
                self.get_logger().warning(
                    f'{name}: {count} malformed frame(s) so far, dropped; last: '
                    f'{device.last_malformed}')
        if self._levels_changed(status, self._stale):
            self.publish_diagnostics()

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
                with self.gate.calling(srv_name):
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
                reason = self.gate.arming_reason(True)
                if reason:
                    self.get_logger().warning(f'refused: {reason}')
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
            refused = self.gate.set_enabled(
                bool(changed['commands_enabled']),
                how='set at run time through the parameter services; the caller is not known '
                    'to the node (restrict who may set it with SROS2: security/policy.xml)')
            if refused:  # checked in _on_set_parameters: not reached
                self.get_logger().error(f'commands_enabled not applied: {refused}')

    # --- shutdown -------------------------------------------------------------------------
    def destroy_node(self) -> None:
        """Stop the periodic work, the commanders and the bus thread (closes the bus)."""
        self._ready = False
        periodic = getattr(self, 'periodic', None)
        if periodic is not None:
            periodic.stop()
        for commander in self.commanders.values():
            commander.destroy()
        self.commanders.clear()
        if self.gate is not None:
            self.gate.attach_bus(None)  # a command from now on is answered 'shutting down'
        if self.can_io is not None:
            self.can_io.stop()
            self.can_io = None
        super().destroy_node()
