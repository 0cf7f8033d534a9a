# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Per-device state, the contract between the protocol layer and the engine.

``Device.handle_frame`` runs on the receive thread for every frame of the device's IDs:
it decodes, updates the state under the device's lock, returns quickly and never raises for
bad input. The reports are plain dataclasses that mirror sensor_msgs/BatteryState and
DiagnosticStatus; no rclpy here. The flow around them: doc/architecture.md, "Data".
"""
from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from typing import (Any, Callable, ClassVar, Generic, Iterable, Mapping, NamedTuple, Protocol,
                    TypeVar)

from ams_can_bridge.devices.commands import Command
from ams_can_bridge.devices.config import DeviceConfig
from ams_can_bridge.devices.ports import Armed, InfoLog, SendFrame
from ams_can_bridge.errors import ConfigError, ParamError, ProtocolError
from ams_can_bridge.parameters import ParamSpec
# The message enums live with the protocols (which name them too); devices take them from here.
from ams_can_bridge.protocols.battery_state import (  # noqa: F401 (re-exported)
    Level, PowerSupplyHealth, PowerSupplyStatus, PowerSupplyTechnology)

NAN = math.nan


@dataclass
class BatteryReport:
    """sensor_msgs/BatteryState without ROS: NaN = unknown, current < 0 while discharging."""

    stamp: float = NAN  # wall-clock time (s since epoch) the primary frame was received
    voltage: float = NAN
    temperature: float = NAN
    current: float = NAN
    charge: float = NAN
    capacity: float = NAN
    design_capacity: float = NAN
    percentage: float = NAN  # 0..1
    power_supply_status: int = PowerSupplyStatus.UNKNOWN
    power_supply_health: int = PowerSupplyHealth.UNKNOWN
    power_supply_technology: int = PowerSupplyTechnology.UNKNOWN
    present: bool = False
    cell_voltage: list[float] = field(default_factory=list)
    cell_temperature: list[float] = field(default_factory=list)
    location: str = ''
    serial_number: str = ''


@dataclass
class DiagnosticReport:
    """diagnostic_msgs/DiagnosticStatus without ROS (name/hardware_id are set by the node)."""

    level: Level
    message: str
    values: dict[str, str] = field(default_factory=dict)


class Sent(NamedTuple):
    """What the bridge sends on one ID for a device, and whether it repeats on its own."""

    what: str
    periodic: bool = False  # a heartbeat, a keep-alive, a repeat: not only on a call


class Codec(Protocol):
    """
    What a device needs of its protocol codec (protocols/__init__.py lists the codec contract).

    A device type narrows ``codec`` to its own codec class, for the encoders it calls.
    """

    @property
    def arbitration_ids(self) -> frozenset[int]:
        """Return the IDs the codec decodes."""

    @property
    def is_extended_id(self) -> bool:
        """Tell whether its IDs are 29-bit."""

    def decode(self, arbitration_id: int, data: bytes, /) -> object:
        """Return the reading of one frame; raise a ProtocolError for a malformed one."""


ConfigT = TypeVar('ConfigT', bound=DeviceConfig)


def device_params(device_cls: type['Device[Any]']) -> list[ParamSpec]:
    """List every parameter of a device type: common, its own, its command services'."""
    return (common_params(device_cls) + list(device_cls.PARAMS)
            + list(device_cls.COMMAND_PARAMS))


def common_params(device_cls: type['Device[Any]']) -> list[ParamSpec]:
    """List the parameters every device instance has, with the device type's defaults."""
    specs = [
        ParamSpec('frame_id', str, '', 'header.frame_id of the BatteryState messages'),
        ParamSpec('location', str, '', 'BatteryState.location (where the pack sits)'),
        ParamSpec('serial_number', str, '', 'BatteryState.serial_number'),
        ParamSpec('stale_timeout', float, 5.0 * device_cls.BROADCAST_PERIOD,
                  'seconds without a status frame before the device is STALE '
                  '(default 5 x its broadcast period)', low=0.01, high=3600.0),
    ]
    if device_cls.DEFAULT_BASE_ID is not None:
        specs.append(ParamSpec('base_id', int, device_cls.DEFAULT_BASE_ID,
                               f'first CAN ID of the device (default {device_cls.DEFAULT_BASE_ID}'
                               f' = 0x{device_cls.DEFAULT_BASE_ID:X})', low=0,
                               high=(1 << device_cls.ID_BITS) - 1))
    if device_cls.EXTENDED_ID_CHOICE:
        specs.append(ParamSpec('extended_id', bool, device_cls.DEFAULT_EXTENDED_ID,
                               device_cls.EXTENDED_ID_HELP))
    return specs


class Device(Generic[ConfigT]):
    """
    Base of every device state: counters, staleness, locking, malformed-frame bookkeeping.

    Subclasses are ``Device[<Type>Config]`` (their typed configuration,
    devices/generated_configs.py): they set the class constants and ``Config``, build their
    ``codec`` in __init__ (a type without one codec overrides arbitration_ids, frame_ids,
    is_extended_id and handle_frame), and implement ``_handle`` (decoded reading -> state;
    return True for the primary status frame), ``_battery_report`` and
    ``_diagnostic_report``.
    """

    TYPE: ClassVar[str] = ''
    BROADCAST_PERIOD: ClassVar[float] = 1.0  # s, of the primary status frame
    DEFAULT_BASE_ID: ClassVar[int | None] = None
    ID_BITS: ClassVar[int] = 11  # 29 for devices on extended (CAN 2.0B) IDs
    EXTENDED_ID_CHOICE: ClassVar[bool] = False
    DEFAULT_EXTENDED_ID: ClassVar[bool] = False
    EXTENDED_ID_HELP: ClassVar[str] = 'use 29-bit (extended) CAN IDs'
    PARAMS: ClassVar[list[ParamSpec]] = []  # type-specific, besides common_params()
    # What the device's command services use (declared with the device, passed in params
    # like PARAMS: the device itself reads some, e.g. a pack capacity or cell counts).
    COMMAND_PARAMS: ClassVar[list[ParamSpec]] = []
    # Other devices this type uses: {parameter key naming the instance: device TYPE}, e.g.
    # the AMS's {'current_sensor': 'ivt_s'}. DeviceSet resolves each (the parameter, or '' =
    # the first instance of that type) and calls attach_link(); the parameter keeps the
    # value the user gave (the resolved instance shows in the diagnostics instead).
    LINKS: ClassVar[Mapping[str, str]] = {}
    # The command services of the type, one row each (devices/commands.py): what the one
    # command pipeline (engine/commands.py) runs and the ROS adapter offers.
    COMMANDS: ClassVar[tuple[Command, ...]] = ()
    # std_msgs/Float32 topics '<instance>/<suffix>' the engine emits for the type (a pack's)
    FIGURES: ClassVar[tuple[str, ...]] = ()

    # The typed, frozen configuration class of the device type (devices/generated_configs.py,
    # generated from device_params(); test_device_configs.py checks they agree).
    Config: type[ConfigT]
    codec: Codec

    def __init__(self, name: str, config: ConfigT | Mapping[str, Any],
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Check the configuration (ParamError naming every bad value) and set up the state."""
        self.name = name
        self.clock = clock
        self.lock = threading.Lock()
        self.frames_received = 0
        self.frames_malformed = 0
        self.last_malformed: str = ''
        self.last_seen: float | None = None  # clock() of the last valid primary frame
        if not isinstance(config, DeviceConfig):
            config = self.Config.from_values(config)
        elif not isinstance(config, self.Config):
            raise ConfigError(f'{type(self).__name__} is configured by {self.Config.__name__}, '
                              f'not by a {type(config).__name__}')
        problems = self.config_problems(config)
        if problems:
            raise ParamError('; '.join(problems))
        self.config = config
        self._config_changes = 0
        self.stale_timeout = self._stale_timeout(config)

    # --- configuration ----------------------------------------------------------------------
    def config_problems(self, config: ConfigT,
                        keys: Iterable[str] | None = None) -> list[str]:
        """
        Say what is wrong with a configuration ([] = usable), each naming the parameter.

        ``keys`` limits the check to the values being changed. The ranges ROS declares are
        checked by the node before; this is what only the device type knows.
        """
        return []

    def config_reason(self, key: str, value: Any) -> str | None:
        """Say why '<name>.<key>' cannot take this value (None = acceptable)."""
        try:
            new = self.config.replace({key: value})
        except ParamError as exc:
            return f'{self.name}.{key} = {value!r} refused: {exc}'
        return '; '.join(self.config_problems(new, [key])) or None

    def configure(self, changes: Mapping[str, Any]) -> ConfigT:
        """
        Apply parameter changes ({key: value}) as one new configuration, swapped in whole.

        Raises ParamError (a ValueError, naming the parameter) and keeps the old
        configuration when a value is not usable. The values it has already change nothing.
        """
        new = self.config.replace(changes)
        if new == self.config:  # the values it has: nothing changes (no swap, no follow-up)
            return new
        problems = self.config_problems(new, changes)
        if problems:
            raise ParamError('; '.join(problems))
        with self.lock:
            old, self.config = self.config, new
            self._config_changes += 1
            self.stale_timeout = self._stale_timeout(new)
            self._reconfigured(old, new)
        return new

    def _reconfigured(self, old: ConfigT, new: ConfigT) -> None:
        """Follow a configuration change (lock held); the device types that need it."""

    # --- the command side (besides COMMANDS) ------------------------------------------------
    def attach_senders(self, send: SendFrame, log: InfoLog) -> list[Armed]:
        """
        Make the device's periodic senders (stopped), sending through ``send``; list them.

        ``send`` is the gate's periodic path (never waits). The command side arms them
        while commands are enabled and the bus is connected, and disarms them at once.
        """
        return []

    def start_command(self) -> str | None:
        """Name the command run once when the device is heard while commands are enabled."""
        return None

    def heard(self) -> bool:
        """Tell whether a valid primary frame of the device came."""
        return self.last_seen is not None

    def attach_link(self, key: str, device: 'Device[Any]', origin: str) -> None:
        """
        Take the instance DeviceSet resolved for one of LINKS (origin: how it was chosen).

        Lock order: a device reads a linked device only while NOT holding its own lock.
        """
        raise NotImplementedError(f'{type(self).__name__} declares no link {key!r}')

    def attach_members(self, devices: Mapping[str, 'Device[Any]']) -> None:
        """Take the instances of the node (in ``devices`` order); a pack picks its members."""

    def _stale_timeout(self, config: ConfigT) -> float:
        return float(config.stale_timeout or 5.0 * self.BROADCAST_PERIOD)

    # --- receive side (bus thread) -------------------------------------------------------
    @property
    def arbitration_ids(self) -> frozenset[int]:
        """Return every CAN ID this device consumes (the node filters and dispatches on them)."""
        return self.codec.arbitration_ids

    @property
    def is_extended_id(self) -> bool:
        """Tell whether the device's own IDs are 29-bit."""
        return self.codec.is_extended_id

    @property
    def frame_ids(self) -> frozenset[tuple[int, bool]]:
        """Return every (CAN ID, 29-bit) the device consumes; a device may use both widths."""
        extended = self.is_extended_id
        return frozenset((can_id, extended) for can_id in self.arbitration_ids)

    def sent_ids(self, config: ConfigT | None = None) -> dict[tuple[int, bool], Sent]:
        """
        Return each (CAN ID, 29-bit) the bridge may send for this device, and what.

        ``config``: judge this configuration instead of the current one (a run-time set).
        The overlap check (``device_set.overlap_problems``) refuses an ID two instances
        send, and an ID one sends periodically while another reads it.
        """
        return {}

    def handle_frame(self, arbitration_id: int, data: bytes, stamp: float) -> bool:
        """
        Decode and apply one frame; True when it was the primary status frame.

        Never raises for bad input: a ProtocolError is counted as malformed and
        remembered (the node logs it throttled); nothing of it reaches the state.
        """
        try:
            reading = self.codec.decode(arbitration_id, data)
        except ProtocolError as exc:
            with self.lock:
                self._count_malformed(str(exc))
            return False
        with self.lock:
            self.frames_received += 1
            primary = self._handle(reading, stamp)
            if primary:
                self.last_seen = self.clock()
            return primary

    def _count_malformed(self, why: str) -> None:
        """Count a malformed frame; ``why`` becomes 'last malformed frame' (lock held)."""
        self.frames_malformed += 1
        self.last_malformed = why

    def _handle(self, reading: Any, stamp: float) -> bool:
        raise NotImplementedError

    @property
    def revision(self) -> int:
        """Count frames taken (valid or not) and configuration changes: reports change then."""
        return self.frames_received + self.frames_malformed + self._config_changes

    # --- reports: what the engine publishes -------------------------------------------
    def is_stale(self) -> bool:
        """Tell whether no primary frame came within stale_timeout (or none ever)."""
        return self.last_seen is None or self.clock() - self.last_seen > self.stale_timeout

    def battery_report(self) -> BatteryReport:
        """
        Build the BatteryState to publish now.

        While the device is stale the report says present False and carries no
        measurement: NaN, not the last values, so a plot shows a gap instead of a flat
        line that looks alive (the last real values are in the last present message).
        Configured values (capacity, technology, location) stay.
        """
        with self.lock:
            report = self._battery_report()
        if self.is_stale():
            report = stale_report(report)
        config = self.config
        report.location = config.location or ''
        report.serial_number = config.serial_number or ''
        return report

    def snapshot(self) -> tuple[BatteryReport, dict[str, tuple[int, int, list[float]]]]:
        """
        Return the BatteryState report and the arrays of one moment (one lock acquisition).

        The engine's view of a primary frame: a frame taken between the report and the
        arrays could otherwise give a message whose arrays belong to the next frame.
        """
        with self.lock:
            report = self._battery_report()
            arrays = self._extra_arrays()
            stale = self.is_stale()
        if stale:
            report = stale_report(report)
        config = self.config
        report.location = config.location or ''
        report.serial_number = config.serial_number or ''
        return report, arrays

    def diagnostic_report(self) -> DiagnosticReport:
        """Build level, one-line summary and every decoded field; STALE wins while silent."""
        with self.lock:
            report = self._diagnostic_report()
            report.values.setdefault('frames received', str(self.frames_received))
            report.values.setdefault('frames malformed', str(self.frames_malformed))
            if self.last_malformed:
                report.values.setdefault('last malformed frame', self.last_malformed)
        if self.is_stale():
            waited = ('never heard' if self.last_seen is None
                      else f'silent for {self.clock() - self.last_seen:.1f} s')
            report.level = Level.STALE
            report.message = f'stale: {waited} (stale_timeout {self.stale_timeout:g} s)'
        return report

    def diagnostic_level(self) -> Level:
        """
        Return the level diagnostic_report() gives now, without building its values.

        The node's watch asks for it several times a second under load, to publish early
        on a change; the values (up to ~100 formatted strings a device) only once a second.
        """
        with self.lock:
            level = self._diagnostic_report(with_values=False).level
        return Level.STALE if self.is_stale() else level

    def start_log(self) -> tuple[list[str], list[str]]:
        """Return what the start log says of this device beyond its IDs: (INFO, WARN) lines."""
        return [], []

    def _battery_report(self) -> BatteryReport:
        raise NotImplementedError

    def _diagnostic_report(self, with_values: bool = True) -> DiagnosticReport:
        """Build level, message and (with_values) the values (lock held)."""
        raise NotImplementedError

    def extra_arrays(self) -> dict[str, tuple[int, int, list[float]]]:
        """List extra Float32MultiArray topics: '<suffix>' -> (rows, cols, row-major data)."""
        with self.lock:
            return self._extra_arrays()

    def _extra_arrays(self) -> dict[str, tuple[int, int, list[float]]]:
        """Build the extra arrays (lock held); the device types that have some."""
        return {}


def stale_report(report: BatteryReport) -> BatteryReport:
    """Return the report of a silent device: present False, every measurement NaN."""
    return BatteryReport(
        stamp=report.stamp, capacity=report.capacity, design_capacity=report.design_capacity,
        power_supply_technology=report.power_supply_technology, present=False,
        cell_voltage=[NAN] * len(report.cell_voltage),
        cell_temperature=[NAN] * len(report.cell_temperature))


def current_status(current_a: float, idle_band_a: float = 0.05) -> PowerSupplyStatus:
    """CHARGING / DISCHARGING / NOT_CHARGING from a ROS-signed current (< 0 discharging)."""
    if current_a != current_a:
        return PowerSupplyStatus.UNKNOWN
    if current_a > idle_band_a:
        return PowerSupplyStatus.CHARGING
    if current_a < -idle_band_a:
        return PowerSupplyStatus.DISCHARGING
    return PowerSupplyStatus.NOT_CHARGING
