"""
The extension point the node calls on a device's command services (python-can listener style).

For each device instance whose type is in ``registry.COMMANDERS`` the node builds
``cls(node, device, name)``; ``cls`` must derive from :class:`Commander`. The node calls these
methods, from the executor (commands_enabled) or the shutting-down thread (destroy).
Parameters are not the commander's: the node checks and applies a device's parameters on the
device itself (``Device.config_reason`` / ``Device.configure``), and a commander reads the
device's current configuration when a call comes.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any


class Commander(ABC):
    """The command services of one device instance (``<name>/...``)."""

    @abstractmethod
    def __init__(self, node: Any, device: Any, name: str) -> None:
        """Create the services; raise ConfigError/ParamError naming any bad start value."""

    def on_commands_enabled(self, enabled: bool) -> None:
        """Follow the commands_enabled parameter (stop anything that transmits when false)."""

    @abstractmethod
    def destroy(self) -> None:
        """Stop background work and remove the services (the node is shutting down)."""
