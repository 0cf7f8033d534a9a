# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Print the bridge's topics and services as Markdown tables, from the devices and their rows.

Usage: python scripts/interface_table.py. The doc build runs it for doc/topics_services.md
(doc/docgen.py), so the page is whatever the code offers; test/test_package_docs.py compares the
tables with what a running bridge with every device type offers.

Where the rows come from is one function each: :func:`device_services` (the command rows
each device type declares, ``Device.COMMANDS``: the ROS adapter, ros/services.py, offers one
service per row) and :func:`device_arrays` (the array topics a device publishes beside its
BatteryState). Neither needs ROS: in a doc build without it, doc/docgen.py runs this with
Sphinx's mocks for the ROS modules and the tables come out the same.
"""
from __future__ import annotations

from dataclasses import dataclass
import sys
from typing import Any, Callable, Iterator

from ams_can_bridge import registry
from ams_can_bridge.devices.base import Device, device_params

BATTERY_STATE = 'sensor_msgs/msg/BatteryState'
MULTI_ARRAY = 'std_msgs/msg/Float32MultiArray'
# The node's own topics (ros/sink.py), absolute names: (topic, type, when).
NODE_TOPICS = (
    ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
     'every `diagnostics_period`, and early on a level change'),
    ('/clock', 'rosgraph_msgs/msg/Clock', 'only in a replay with `can.replay_clock: true`'),
)


@dataclass(frozen=True)
class ServiceRow:
    """One service of a device instance: ``<name>/<service>``."""

    service: str
    srv_type: str  # 'std_srvs/srv/Trigger'
    what: str = ''  # what it does, in words (the row's: a refusal says "to <what>")


def ros_type_name(cls: Any, kind: str) -> str:
    """Return 'package/kind/Name' for a ROS message or service class (or Sphinx's mock)."""
    return f'{cls.__module__.split(".")[0]}/{kind}/{cls.__name__}'


def default_device(device_type: str, variant: str | None) -> Device:
    """Build an instance named after its type, with every parameter at its default."""
    cls = registry.device_class(device_type, variant)
    return cls(device_type, {spec.key: spec.default for spec in device_params(cls)})


def device_services(device_type: str, variant: str | None = None) -> list[ServiceRow]:
    """Return the services of one device type (and variant): its command rows, in order."""
    cls = registry.device_class(device_type, variant)
    return [ServiceRow(row.service, srv_type_name(row.request.value),
                       row.what + (f' (false: {row.what_false})' if row.what_false else ''))
            for row in cls.COMMANDS]


def srv_type_name(request: str) -> str:
    """Return 'std_srvs/srv/Trigger' for a row's request kind 'std_srvs/Trigger'."""
    package, _, name = request.partition('/')
    return f'{package}/srv/{name}'


def device_arrays(device_type: str, variant: str | None = None) -> list[str]:
    """Return the suffixes of the Float32MultiArray topics a device type publishes."""
    cls = registry.device_class(device_type, variant)
    if cls._extra_arrays is Device._extra_arrays:
        return []  # no arrays; the instance may need files (dbc), so none is built
    return sorted(default_device(device_type, variant).extra_arrays())


def variants(device_type: str) -> list[str | None]:
    """Return the variants of a device type ([None] when it has one wire form)."""
    return list(registry.VARIANTS.get(device_type, {})) or [None]


def per_type(rows: Callable[[str, str | None], list]) -> Iterator[tuple[str, list]]:
    """Yield (device type label, rows); variants are one entry unless their rows differ."""
    for device_type in registry.DEVICE_TYPES:
        found = {variant: rows(device_type, variant) for variant in variants(device_type)}
        if len({repr(r) for r in found.values()}) == 1:
            yield f'`{device_type}`', next(iter(found.values()))
        else:
            for variant, got in found.items():
                yield f'`{device_type}` (`variant: {variant}`)', got


def topics_table() -> list[str]:
    """Return the topics table: per device instance, then the node's own."""
    lines = ['| topic | type | published by |', '|---|---|---|',
             f'| `<name>/battery_state` | `{BATTERY_STATE}` | every device type |']
    arrays: dict[str, list[str]] = {}
    for label, suffixes in per_type(device_arrays):
        for suffix in suffixes:
            arrays.setdefault(suffix, []).append(label)
    for suffix, labels in arrays.items():
        lines.append(f'| `<name>/{suffix}` | `{MULTI_ARRAY}` | {", ".join(labels)} |')
    for device_type in registry.DEVICE_TYPES:  # std_msgs/Float32 figures (a pack's)
        for suffix in registry.device_class(device_type).FIGURES:
            lines.append(f'| `<name>/{suffix}` | `std_msgs/msg/Float32` | `{device_type}` |')
    for topic, msg_type, when in NODE_TOPICS:
        lines.append(f'| `{topic}` | `{msg_type}` | the node: {when} |')
    return lines


def services_table() -> list[str]:
    """Return the services table: per device type, its services under ``<name>/``."""
    rows = list(per_type(device_services))
    words = any(row.what for _, services in rows for row in services)
    lines = ['| device type | service | type |' + (' what it does |' if words else ''),
             '|---|---|---|' + ('---|' if words else '')]
    for label, services in rows:
        if not services:
            lines.append(f'| {label} | (none) | |' + (' |' if words else ''))
        for row in services:
            lines.append(f'| {label} | `<name>/{row.service}` | `{row.srv_type}` |'
                         + (f' {row.what} |' if words else ''))
    return lines


def main() -> None:
    """Print the topics table, then the services table."""
    print('\n'.join(topics_table()))
    print('\nServices, each under its device instance `<name>/`:\n')
    print('\n'.join(services_table()))


if __name__ == '__main__':
    sys.exit(main())
