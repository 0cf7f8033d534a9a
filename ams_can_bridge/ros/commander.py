"""
The extension point the node calls on a device's command services (python-can listener style).

For each device instance whose type is in ``registry.COMMANDERS`` the node builds
``cls(gate, device, name, host)``; ``cls`` must derive from :class:`Commander`. Frames go to
the bus only through ``gate`` (``engine.gate.CommandPort``: the commands_enabled gate, the
bus wait, the send locks, the command log line); ``host`` (:class:`ServiceHost`, the node)
only creates and removes services. The gate calls ``on_commands_enabled`` (a listener) from
the thread that changed commands_enabled; the node calls ``destroy`` at shutdown.
Parameters are not the commander's: the node checks and applies a device's parameters on the
device itself (``Device.config_reason`` / ``Device.configure``), and a commander reads the
device's current configuration when a call comes.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, Callable, Generic, Protocol, TypeVar

from ams_can_bridge import registry
from ams_can_bridge.devices.base import Device
from ams_can_bridge.engine.gate import CommandPort
from ams_can_bridge.errors import ConfigError


class ServiceHost(Protocol):
    """What a commander needs of the node: its services, its logger, its parameters."""

    service_group: Any

    @property
    def context(self) -> Any:
        """Return rclpy's context: ``context.ok()`` is false once ROS is shutting down."""

    def create_service(self, srv_type: Any, srv_name: str, callback: Callable,
                       **kwargs: Any) -> Any:
        """Create a service (logged, see the node)."""

    def destroy_service(self, service: Any) -> Any:
        """Remove a service."""

    def get_logger(self) -> Any:
        """Return the node's logger."""

    def set_parameters_atomically(self, parameters: list) -> Any:
        """Set parameters all or none (the EVMS3 read-back)."""


DeviceT = TypeVar('DeviceT', bound=Device)


class Commander(ABC, Generic[DeviceT]):
    """The command services of one device instance (``<name>/...``)."""

    def __init__(self, gate: CommandPort, device: DeviceT, name: str,
                 host: ServiceHost) -> None:
        """Keep the gate, the device and the host; follow commands_enabled from now on."""
        self.gate = gate
        self.device = device
        self.name = name
        self.host = host
        self._services: list[Any] = []
        gate.add_listener(self.on_commands_enabled)

    def on_commands_enabled(self, enabled: bool) -> None:
        """Follow the commands_enabled parameter (stop anything that transmits when false)."""

    def _service(self, srv_type: Any, suffix: str, callback: Callable) -> None:
        """Offer ``<name>/<suffix>`` in the host's service group (callbacks may wait)."""
        self._services.append(self.host.create_service(
            srv_type, f'{self.name}/{suffix}', callback,
            callback_group=self.host.service_group))

    def _remove_services(self) -> None:
        self.gate.remove_listener(self.on_commands_enabled)
        for service in self._services:
            self.host.destroy_service(service)
        self._services.clear()

    @abstractmethod
    def destroy(self) -> None:
        """Stop background work and remove the services (the node is shutting down)."""


def make_commander(gate: CommandPort, device: Device, name: str,
                   host: ServiceHost) -> Commander | None:
    """Build the commander ``registry.COMMANDERS`` names for the device's type (None: none)."""
    path = registry.COMMANDERS.get(device.TYPE)
    if path is None:
        return None
    # every module COMMANDERS names ships with the package: a missing one is a broken
    # install, and the error says so (test_sim_runner.py::test_registry_paths_all_import)
    cls = registry.load(path)
    if not (isinstance(cls, type) and issubclass(cls, Commander)):
        raise ConfigError(f'{path} is not a Commander (ams_can_bridge.ros.commander)')
    return cls(gate, device, name, host)
