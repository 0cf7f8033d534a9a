# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
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

import difflib
import re
import time
from typing import Any, Callable, Collection, Iterable, Mapping

from ams_can_bridge import registry
from ams_can_bridge.devices.base import Device, device_params, Sent
from ams_can_bridge.errors import ConfigError, ParamError
from ams_can_bridge.parameters import MAX_DEVICES, ParamSpec
from ams_can_bridge.protocols.sma import SMA_IDS

Declare = Callable[[str, ParamSpec], Any]
# IDs that two devices of different types may both read: they come from one sender. The SMA
# IDs are fixed by the protocol (one SMA sender per bus), and a BMS16 sends them besides its
# own frames: an sma instance then shows the same pack through the SMA protocol (the demo
# does). Neither device sends on them. Every other shared ID stops the bridge at start.
SHARED_IDS: dict[str, frozenset[int]] = {'sma': SMA_IDS, 'bms16': SMA_IDS}
# Parameters a node may be given that are not the bridge's: rclpy's QoS overrides
# (qos_overrides./topic.publisher.depth ...).
FOREIGN_PREFIXES = ('qos_overrides.',)
# Parameters every rclpy node declares itself (log2bag, without rclpy, knows them by name).
ROS_NODE_PARAMS = frozenset({'use_sim_time', 'start_type_description_service'})
# An instance name becomes a topic and service namespace (<name>/battery_state), so it must
# be one ROS name token: letters, digits and underscores, not starting with a digit (rcl).
INSTANCE_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')
INSTANCE_NAME_RULE = ('an instance name names its topics and services (<name>/battery_state), '
                      'so it must be a ROS name: letters, digits and underscores, not starting '
                      'with a digit')
OVERLAP_ADVICE = ('Two instances on one ID would both decode its frames (and both send, with '
                  'commands armed). Move one of them (<name>.base_id) or remove it from '
                  'devices')


def variant_spec(device_type: str) -> ParamSpec:
    """Return the '<name>.variant' parameter of a type with several wire forms (VARIANTS)."""
    variants = tuple(registry.VARIANTS[device_type])
    return ParamSpec('variant', str, variants[0], registry.VARIANT_HELP.get(
        device_type, f'wire form of the {device_type}: ' + ', '.join(variants)),
        choices=variants)


class DeviceSet:
    """Device instances by name (each with its typed configuration) and the dispatch."""

    def __init__(self, names: Iterable[str], declare: Declare,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Build every instance of ``names``; raise ConfigError saying what to change."""
        names = list(names)
        if len(names) > MAX_DEVICES:  # before anything is declared or built
            raise ConfigError(f'devices has {len(names)} instances: at most {MAX_DEVICES} are '
                              'allowed (one bridge per bus; run another bridge for more)')
        if len(set(names)) != len(names):
            raise ConfigError(f'devices = {names}: instance names must be unique')
        self.devices: dict[str, Device] = {}
        for name in names:
            self._add(name, declare, clock)
        # '<instance>.<key>' -> what the link resolved to, for the start-up log
        self.links: dict[str, str] = {}
        self._resolve_links()
        for device in self.devices.values():
            device.attach_members(self.devices)  # a pack checks and takes its members
        self._check_overlaps()
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
        if not isinstance(name, str) or not INSTANCE_NAME.fullmatch(name):
            suggestion = re.sub(r'\W', '_', str(name))
            suggestion = f'_{suggestion}' if suggestion[:1].isdigit() else suggestion
            raise ConfigError(f'devices: {name!r} is not a usable instance name: '
                              f'{INSTANCE_NAME_RULE} (e.g. {suggestion or "pack"!r})')
        type_spec = ParamSpec('type', str, name, 'device type: ' + ', '.join(
            registry.DEVICE_TYPES), choices=registry.DEVICE_TYPES)
        try:
            device_type = declare(f'{name}.type', type_spec)
        except ParamError:
            device_type = None
        if isinstance(device_type, str) and device_type in registry.BROKEN:
            raise ConfigError(f'{name}.type: {registry.unknown(device_type)}')
        if device_type not in registry.DEVICE_TYPES:
            raise ConfigError(
                f'{name}.type: unknown device type for instance {name!r}; set {name}.type to '
                'one of ' + ', '.join(registry.DEVICE_TYPES))
        variant = None
        variants = registry.VARIANTS.get(device_type)
        if variants:
            # read first: the variant decides which parameters the instance has
            variant = declare(f'{name}.variant', variant_spec(device_type))
        cls = registry.device_class(device_type, variant)
        values = {spec.key: declare(f'{name}.{spec.key}', spec) for spec in device_params(cls)}
        try:
            device = cls(name, values, clock)
        except ValueError as exc:  # ConfigError, or a protocol codec refusing its IDs
            raise ConfigError(f'device {name!r} ({device_type}): {exc}') from None
        self.devices[name] = device

    def _check_overlaps(self) -> None:
        """Raise ConfigError naming every pair of instances on the same CAN IDs."""
        problems = overlap_problems(self.devices)
        if problems:
            raise ConfigError(overlap_error(problems))

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


def _owners(devices: Mapping[str, Device], sent: Mapping[str, Mapping[tuple[int, bool], Sent]]
            ) -> tuple[dict[tuple[int, bool], list[str]],
                       dict[tuple[int, bool], list[tuple[str, Sent]]]]:
    """Return who reads and who sends each ID, in device order: one pass over every ID."""
    readers: dict[tuple[int, bool], list[str]] = {}
    senders: dict[tuple[int, bool], list[tuple[str, Sent]]] = {}
    for name, device in devices.items():
        for can_id in device.frame_ids:
            readers.setdefault(can_id, []).append(name)
        for can_id, what in (sent[name] if name in sent else device.sent_ids()).items():
            senders.setdefault(can_id, []).append((name, what))
    return readers, senders


def overlap_problems(devices: Mapping[str, Device],
                     sent: Mapping[str, Mapping[tuple[int, bool], Sent]] | None = None
                     ) -> list[str]:
    """
    Return one problem per pair of instances that share CAN IDs they may not share.

    Read by both (except the SMA IDs read by an sma and a bms16 instance: one sender), sent
    by both, or sent periodically by one (heartbeat, keep-alive) and read by the other. An
    ID one sends only on a call while another reads it is left alone (the AMS's
    override_bank_count 0x351 at the default base is the SMA limits ID, as it always was). Each
    ID is visited once with its owners, so the check grows with the number of IDs, not
    with the square of the instances (MAX_DEVICES bounds the owners of one ID). ``sent``:
    the IDs to judge for some instances instead of their own (a run-time set).
    """
    readers, senders = _owners(devices, sent or {})
    order = {name: i for i, name in enumerate(devices)}
    read: dict[tuple[str, str], set[tuple[int, bool]]] = {}
    for can_id, names in readers.items():
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                ta, tb = devices[a].TYPE, devices[b].TYPE
                if ta != tb and not can_id[1] and can_id[0] in (
                        SHARED_IDS.get(ta, frozenset()) & SHARED_IDS.get(tb, frozenset())):
                    continue
                read.setdefault((a, b), set()).add(can_id)
    # a pair already named for reading an ID is not named again for sending it
    both: dict[tuple[str, str], tuple[set[tuple[int, bool]], dict[str, None], dict[str, None]]]
    both = {}
    periodic: dict[tuple[str, str, str], set[tuple[int, bool]]] = {}
    for can_id, owners in senders.items():
        for i, (a, what_a) in enumerate(owners):
            for b, what_b in owners[i + 1:]:
                if a != b and can_id not in read.get((a, b), ()):
                    ids, whats_a, whats_b = both.setdefault((a, b), (set(), {}, {}))
                    ids.add(can_id)
                    whats_a[what_a.what] = whats_b[what_b.what] = None
        for a, what_a in owners:
            for b in readers.get(can_id, ()):
                pair = _pair(a, b, order)
                if what_a.periodic and b != a and can_id not in read.get(pair, ()) \
                        and can_id not in both.get(pair, ((),))[0]:
                    periodic.setdefault((a, b, what_a.what), set()).add(can_id)
    problems = [(order[a], order[b], 0, f'{a} ({devices[a].TYPE}) and {b} '
                 f'({devices[b].TYPE}) both use {format_ids(ids)}')
                for (a, b), ids in read.items()]
    problems += [(order[a], order[b], 1, f'{a} ({devices[a].TYPE}) and {b} '
                  f'({devices[b].TYPE}) both send {format_ids(ids)} ({a}: {", ".join(wa)}; '
                  f'{b}: {", ".join(wb)})') for (a, b), (ids, wa, wb) in both.items()]
    problems += [(order[a], order[b], 2, f'{a} ({devices[a].TYPE}) sends its {what} on '
                  f'{format_ids(ids)}, which {b} ({devices[b].TYPE}) reads')
                 for (a, b, what), ids in periodic.items()]
    return [text for *_, text in sorted(problems)]


def overlap_error(problems: list[str]) -> str:
    """Return the one message for every overlap, with what to change."""
    advice = OVERLAP_ADVICE
    if any('keep-alive' in problem for problem in problems):
        advice += ', or turn the keep-alive off (<name>.inverter_keepalive: false)'
    return 'devices overlap: ' + '; '.join(problems) + '. ' + advice


def _pair(a: str, b: str, order: Mapping[str, int]) -> tuple[str, str]:
    return (a, b) if order[a] < order[b] else (b, a)


def unknown_parameter_errors(given: Mapping[str, Any], declared: Collection[str]) -> list[str]:
    """
    Return one message per given parameter that nothing declared, naming what to change.

    ``given``: every value given for this node (params file sections that apply to it,
    ``-p`` overrides), flat dotted names; ``declared``: what the configuration declared.
    A key of a device type's parameter under a name that is no configured instance says
    so; otherwise the nearest declared name is suggested (a typo). Keys of a listed
    instance whose parameters were not declared (its type unknown, or the configuration
    stopped before it) are not judged: what it takes is not known.
    """
    listed = given.get('devices')
    names = [n for n in listed if isinstance(n, str)] if isinstance(listed, (list, tuple)) \
        else []
    instances = {n: given.get(f'{n}.type', n) for n in names}
    known = sorted(n for n in declared if not n.startswith(FOREIGN_PREFIXES))
    built = {n.partition('.')[0] for n in known if '.' in n and not n.endswith('.type')}
    errors = []
    for key in sorted(set(given) - set(declared) - ROS_NODE_PARAMS):
        prefix, dot, rest = key.partition('.')
        unjudged = bool(dot) and prefix in instances and prefix not in built
        if key.startswith(FOREIGN_PREFIXES) or unjudged:
            continue
        errors.append(_unknown_message(key, prefix, rest, instances, known))
    return errors


def _nearest(key: str, candidates: Iterable[str]) -> str:
    match = difflib.get_close_matches(key, list(candidates), n=1, cutoff=0.6)
    return f'; did you mean `{match[0]}`?' if match else ''


def _type_keys(device_type: str) -> set[str]:
    try:
        return {spec.key for spec in device_params(registry.device_class(device_type))}
    except Exception:  # a type that cannot load: no suggestion from it, no crash here
        return set()


def _unknown_message(key: str, prefix: str, rest: str, instances: Mapping[str, Any],
                     known: list[str]) -> str:
    if rest and prefix in instances:
        device_type = instances[prefix]
        owners = [t for t in registry.DEVICE_TYPES if t != device_type and rest in _type_keys(t)]
        other = f' ({rest} is a parameter of type {" / ".join(owners)})' if owners else ''
        return (f'{key}: unknown parameter of device {prefix} (type {device_type}){other}'
                + _nearest(key, [n for n in known if n.startswith(prefix + '.')
                                 or n.endswith('.' + rest)]))
    if rest:
        owners = [t for t in registry.DEVICE_TYPES if rest in _type_keys(t)]
        if owners:
            listed = ', '.join(instances) or 'nothing'
            return (f'{key}: belongs to no configured device: {prefix!r} is not in devices '
                    f'(devices lists {listed}); add {prefix} to devices (with {prefix}.type: '
                    f'{" or ".join(owners)}) or remove the key'
                    + _nearest(key, [n for n in known if n.endswith('.' + rest)]))
    return f'{key}: unknown parameter (the bridge does not declare it)' + _nearest(key, known)


def format_ids(ids: Collection[tuple[int, bool]]) -> str:
    """'0x300-0x301, 0x305' per width, runs of consecutive IDs collapsed; 29-bit marked."""
    parts = []
    for extended in (False, True):
        runs: list[list[int]] = []
        for i in sorted(i for i, e in ids if e == extended):
            if runs and i == runs[-1][1] + 1:
                runs[-1][1] = i
            else:
                runs.append([i, i])
        if runs:
            parts.append(', '.join(f'0x{a:X}' if a == b else f'0x{a:X}-0x{b:X}' for a, b in runs)
                         + (' (29-bit)' if extended else ''))
    return 'ID ' + '; '.join(parts) if len(ids) == 1 else 'IDs ' + '; '.join(parts)
