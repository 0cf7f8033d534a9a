"""
The extension point the node calls on a device's command services (python-can listener style).

For each device instance whose type is in ``registry.COMMANDERS`` the node builds
``cls(node, device, name)``; ``cls`` must derive from :class:`Commander`. The node calls these
methods, each from the executor (parameter hooks) or the shutting-down thread (destroy).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any


class Commander(ABC):
    """The command services of one device instance (``<name>/...``)."""

    @abstractmethod
    def __init__(self, node: Any, device: Any, name: str) -> None:
        """Create the services; raise ConfigError/ParamError naming any bad start value."""

    def validate_parameter(self, full_name: str, value: Any) -> str | None:
        """Return why a parameter set must be refused (shown to the caller), None to allow."""
        return None

    def on_parameters_changed(self, changed: dict[str, Any]) -> None:
        """Take the parameters just set ({full name: value}), after a successful set."""

    def on_commands_enabled(self, enabled: bool) -> None:
        """Follow the commands_enabled parameter (stop anything that transmits when false)."""

    @abstractmethod
    def destroy(self) -> None:
        """Stop background work and remove the services (the node is shutting down)."""
