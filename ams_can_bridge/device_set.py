"""
The devices of one bus, built from parameters without ROS: the bridge node and log2bag both.

``declare(full_name, spec) -> value`` supplies each parameter: the node declares it as a ROS
parameter, log2bag reads it from the parameters file. Either way every value passes the same
checks (``parameters.coerce``), and the same instances, links and dispatch tables come out,
so an offline conversion decodes exactly what the live bridge decodes.

Links between devices (the AMS and its IVT-S) are declared by the device types
(``Device.LINKS``) and resolved here by type, never written back into a configuration: the
parameter keeps the value the user gave ('' stays ''), and ``links`` says what was chosen.
"""
from __future__ import annotations

import time
from typing import Any, Callable, Iterable

from ams_can_bridge import registry
from ams_can_bridge.devices.base import Device, device_params, ParamSpec
from ams_can_bridge.errors import ConfigError, ParamError

Declare = Callable[[str, ParamSpec], Any]


class DeviceSet:
    """Device instances by name (each with its typed configuration) and the dispatch."""

    def __init__(self, names: Iterable[str], declare: Declare,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Build every instance of ``names``; raise ConfigError saying what to change."""
        names = list(names)
        if len(set(names)) != len(names):
            raise ConfigError(f'devices = {names}: instance names must be unique')
        self.devices: dict[str, Device] = {}
        for name in names:
            self._add(name, declare, clock)
        # '<instance>.<key>' -> what the link resolved to, for the start-up log
        self.links: dict[str, str] = {}
        self._resolve_links()
        self.std: dict[int, tuple[Device, ...]] = {}
        self.ext: dict[int, tuple[Device, ...]] = {}
        for device in self.devices.values():
            for can_id, extended in sorted(device.frame_ids):
                table = self.ext if extended else self.std
                table[can_id] = table.get(can_id, ()) + (device,)

    @property
    def filters(self) -> list[tuple[int, bool]]:
        """Return every (arbitration_id, is_extended_id) some device consumes, sorted."""
        return ([(i, False) for i in sorted(self.std)]
                + [(i, True) for i in sorted(self.ext)])

    def handle_targets(self, arbitration_id: int, is_extended_id: bool) -> tuple[Device, ...]:
        """Return the devices a frame of this (id, width) goes to (empty: nobody's)."""
        return (self.ext if is_extended_id else self.std).get(arbitration_id, ())

    def handle_frame(self, arbitration_id: int, data: bytes, is_extended_id: bool,
                     stamp: float) -> list[Device]:
        """Give a frame to the devices of its ID; return those for which it was primary."""
        devices = (self.ext if is_extended_id else self.std).get(arbitration_id)
        if devices is None:
            return []
        if len(devices) == 1:  # most IDs: one device, no comprehension
            device = devices[0]
            return [device] if device.handle_frame(arbitration_id, data, stamp) else []
        return [d for d in devices if d.handle_frame(arbitration_id, data, stamp)]

    def _add(self, name: str, declare: Declare, clock: Callable[[], float]) -> None:
        if not name or '/' in name or '.' in name or name != name.strip():
            raise ConfigError(f'devices: {name!r} is not a usable instance name '
                              '(no empty names, dots, slashes or spaces)')
        type_spec = ParamSpec('type', str, name, 'device type: ' + ', '.join(
            registry.DEVICE_TYPES), choices=registry.DEVICE_TYPES)
        try:
            device_type = declare(f'{name}.type', type_spec)
        except ParamError:
            device_type = None
        if device_type not in registry.DEVICE_TYPES:
            raise ConfigError(
                f'{name}.type: unknown device type for instance {name!r}; set {name}.type to '
                'one of ' + ', '.join(registry.DEVICE_TYPES))
        variant = None
        variants = registry.VARIANTS.get(device_type)
        if variants:
            # read first: the variant decides which parameters the instance has
            variant = declare(f'{name}.variant', ParamSpec(
                'variant', str, next(iter(variants)), 'wire form of the ' + device_type + ': '
                + ', '.join(variants) + ' (docs/protocols.md)', choices=tuple(variants)))
        cls = registry.device_class(device_type, variant)
        values = {spec.key: declare(f'{name}.{spec.key}', spec) for spec in device_params(cls)}
        try:
            device = cls(name, values, clock)
        except ValueError as exc:  # ConfigError, or a protocol codec refusing its IDs
            raise ConfigError(f'device {name!r} ({device_type}): {exc}') from None
        self.devices[name] = device

    def _resolve_links(self) -> None:
        """Give each device the instances its LINKS name ('' = the first of that type)."""
        for name, device in self.devices.items():
            for key, link_type in device.LINKS.items():
                found = [n for n, d in self.devices.items() if d.TYPE == link_type]
                wanted = device.config.value(key) or ''
                if not wanted:
                    if not found:
                        continue
                    wanted = found[0]
                    origin = f'the first {link_type} ({name}.{key} unset)'
                elif wanted in found:
                    origin = f'{name}.{key}'
                else:
                    raise ConfigError(
                        f'{name}.{key} = {wanted!r} is not an {link_type} instance: set it to '
                        + (' or '.join(repr(i) for i in found) if found
                           else "'' (none configured)")
                        + f' or add it to devices with type {link_type}')
                device.attach_link(key, self.devices[wanted], origin)
                self.links[f'{name}.{key}'] = f'{wanted} ({origin})'
