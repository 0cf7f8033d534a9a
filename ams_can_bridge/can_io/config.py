# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Bus configuration of the CAN I/O layer: the can.* parameters, checked before any open."""
from __future__ import annotations

from dataclasses import dataclass, field
import difflib
import inspect
import re

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.input_files import file_problem


# python-can options the bridge sets unless can.options gives them. slcan: python-can reads
# the serial port with a 1 ms timeout by default, so an idle bus costs ~1000 wake-ups a
# second. A read returns as soon as a byte arrives whatever the timeout, so a long one
# costs no latency: 0.5 s makes an idle bridge nearly free (bench/README.md) and still lets
# a stop (Ctrl-C) through within half a second.
INTERFACE_DEFAULTS: dict[str, dict[str, object]] = {
    'slcan': {'timeout': 0.5},
}

# An slcan adapter keeps no bit rate of the bus's: without can.bitrate no 'S' command is sent.
SLCAN_NO_BITRATE = (
    'can.bitrate is 0 with slcan: no bit rate command is sent, so the adapter runs at '
    'whatever it was last set to (by another program, or its power-up default) and may '
    'hear nothing or disturb the bus; set can.bitrate to the bus\'s bit rate (e.g. 500000)')

# Interfaces the bridge opens itself rather than through python-can.
OWN_INTERFACES = ('replay',)
# Keyword arguments python-can's Bus takes for every interface (can.util turns the timing
# ones into a BitTiming; BusABC takes can_filters), whatever the interface class names.
GENERIC_OPTIONS = frozenset({
    'bitrate', 'data_bitrate', 'fd', 'timing', 'state', 'port', 'can_filters', 'context',
    'config_context', 'f_clock', 'brp', 'tseg1', 'tseg2', 'sjw', 'nof_samples', 'strict',
    'nom_brp', 'nom_tseg1', 'nom_tseg2', 'nom_sjw', 'data_brp', 'data_tseg1', 'data_tseg2',
    'data_sjw', 'tdc', 'tdco', 'tdcf'})

_INT = re.compile(r'[+-]?(0x[0-9a-fA-F]+|0o[0-7]+|0b[01]+|\d+)$')
_FLOAT = re.compile(r'[+-]?(\d+\.\d*|\.\d+|\d+)([eE][+-]?\d+)?$')


def _convert(value: str) -> object:
    """Turn an option value string into the int/float/bool/None it obviously is."""
    lowered = value.strip().lower()
    if lowered in ('true', 'yes', 'on'):
        return True
    if lowered in ('false', 'no', 'off'):
        return False
    if lowered in ('none', 'null'):
        return None
    if _INT.match(lowered):
        try:
            return int(lowered, 0)
        except ValueError:  # '010': base 0 refuses leading zeros, decimal is what was meant
            return int(lowered, 10)
    if _FLOAT.match(lowered):
        return float(lowered)
    return value


def parse_options(entries: list[str] | tuple[str, ...] | None) -> dict[str, object]:
    """
    Parse python-can interface options given as 'key=value' strings.

    Values that are obviously numbers or booleans become int/float/bool ('0x10' -> 16,
    '0.5' -> 0.5, 'true' -> True, 'none' -> None); anything else stays a string.
    Raises ConfigError naming the entry when it has no '=' or an empty key.
    """
    options: dict[str, object] = {}
    for entry in entries or ():
        if not isinstance(entry, str) or '=' not in entry:
            raise ConfigError(
                f'can.options entry {entry!r} is not of the form key=value '
                "(e.g. 'sleep_after_open=0' or 'receive_own_messages=false')")
        key, _, value = entry.partition('=')
        key = key.strip()
        if not key or not key.isidentifier():
            raise ConfigError(
                f'can.options entry {entry!r}: {key!r} is not a valid option name '
                '(a python-can keyword argument such as tty_baudrate)')
        options[key] = _convert(value)
    return options


@dataclass
class BusConfig:
    """
    Which bus to open and how (mirrors the bridge's can.* parameters).

    bitrate 0 leaves the adapter as it is; interface 'replay' plays the log file named by
    channel at replay_rate (1.0 = real time, 0 = as fast as possible); record = path of a
    log file (format by extension, as can.Logger) that receives every frame in and out.
    use_bus_time stamps each frame with the driver's receive time (``Message.timestamp``)
    instead of the host clock; a replay always stamps with the log's own timestamps.
    slcan_bulk_read opens slcan with the bridge's block reader (can_io/slcan.py) instead
    of python-can's byte-per-call one.
    """

    interface: str = 'socketcan'
    channel: str = 'can0'
    bitrate: int = 0
    fd: bool = False
    options: dict[str, object] = field(default_factory=dict)
    reconnect_period: float = 1.0
    replay_rate: float = 1.0
    record: str = ''
    use_bus_time: bool = False
    slcan_bulk_read: bool = True

    def __post_init__(self) -> None:
        """Validate the values a user types, naming the field."""
        if isinstance(self.options, (list, tuple)):  # the ROS string-array form
            self.options = parse_options(self.options)
        if not self.interface:
            raise ConfigError("can.interface is empty: use e.g. 'socketcan', 'slcan', 'virtual'")
        if self.bitrate < 0:
            raise ConfigError(f'can.bitrate = {self.bitrate}: must be >= 0 (0 = leave as is)')
        if not self.reconnect_period > 0:
            raise ConfigError(f'can.reconnect_period = {self.reconnect_period}: must be > 0 s')
        if not self.replay_rate >= 0:
            raise ConfigError(f'can.replay_rate = {self.replay_rate}: must be >= 0 '
                              '(1.0 = real time, 0 = as fast as possible)')

    def check(self) -> list[str]:
        """
        Check what can never work, before any attempt to open the bus; return warnings.

        Raises ConfigError naming the setting for an interface python-can does not know, an
        slcan bitrate the adapter protocol has no command for, an option the interface's
        class cannot take (it has no ``**kwargs``: python-can would raise on every attempt),
        and a replay file that does not exist. Those would otherwise be retried forever,
        like an adapter that is not plugged in yet. An option the class does not name but
        may take through ``**kwargs`` is a warning: python-can may ignore it silently, and so
        is slcan without a bit rate (the adapter keeps whatever rate it was last set to).
        """
        import can.interfaces  # python-can's list of interfaces, plugins included
        if self.interface in OWN_INTERFACES:
            problem = file_problem(self.channel)
            if problem:
                raise ConfigError(f'can.channel = {self.channel!r}: the log file to replay '
                                  f'{problem} (can.interface is replay: can.channel names '
                                  'the log)')
            ignored = sorted(self.options) + (['can.bitrate'] if self.bitrate else [])
            return [f'replay ignores {", ".join(ignored)}'] if ignored else []
        valid = sorted(set(can.interfaces.VALID_INTERFACES) | set(OWN_INTERFACES))
        if self.interface not in valid:
            near = difflib.get_close_matches(self.interface, valid, n=1)
            hint = f'; did you mean {near[0]!r}?' if near else ''
            raise ConfigError(f'can.interface = {self.interface!r} is not a python-can '
                              f'interface{hint} (known: {", ".join(valid)})')
        warnings = []
        if self.interface == 'slcan' and self.bitrate:
            from can.interfaces.slcan import slcanBus
            rates = sorted(getattr(slcanBus, '_BITRATES', {}) or ())
            if rates and self.bitrate not in rates:
                raise ConfigError(
                    f'can.bitrate = {self.bitrate}: an slcan adapter has no command for it; '
                    f'use one of {", ".join(str(r) for r in rates)} (or 0 = leave it as is)')
        elif self.interface == 'slcan':
            warnings.append(SLCAN_NO_BITRATE)
        return warnings + self._check_options()

    def _check_options(self) -> list[str]:
        import can.interface
        try:
            bus_class = can.interface._get_class_for_interface(self.interface)
        except Exception:  # driver not installed: that is the adapter's failure, retried
            return []
        named: set[str] = set()
        open_ended = True  # the class's own __init__ takes **kwargs
        for depth, cls in enumerate(c for c in bus_class.__mro__ if '__init__' in c.__dict__):
            try:
                parameters = list(inspect.signature(cls.__dict__['__init__']).parameters
                                  .values())
            except (TypeError, ValueError):
                return []  # a C class without a signature: nothing to tell
            named |= {p.name for p in parameters
                      if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)}
            takes_more = any(p.kind == p.VAR_KEYWORD for p in parameters)
            if depth == 0:
                open_ended = takes_more
            if not takes_more:
                break  # this __init__ takes nothing further: its bases see no more
        unknown = sorted(set(self.options) - named - GENERIC_OPTIONS - {'self'})
        if not unknown:
            return []
        takes = ', '.join(sorted(named - {'self', 'channel', 'args', 'kwargs'}))
        hints = [f'{u} -> {near[0]}' for u in unknown for near in
                 [difflib.get_close_matches(u, sorted(named | GENERIC_OPTIONS), n=1)] if near]
        hint = f'; did you mean {", ".join(hints)}?' if hints else ''
        text = (f'can.options {", ".join(unknown)}: not an argument of python-can\'s '
                f'{bus_class.__name__} (interface {self.interface}; it names {takes}){hint}')
        if not open_ended:
            raise ConfigError(text)
        return [text + '; python-can may ignore it without a word']

    def bus_kwargs(self) -> dict[str, object]:
        """Return the python-can keyword arguments: the interface's defaults, then options."""
        kwargs = dict(INTERFACE_DEFAULTS.get(self.interface, {}))
        kwargs.update(self.options)
        if self.bitrate > 0:
            kwargs['bitrate'] = self.bitrate
        if self.fd:
            kwargs['fd'] = True
        return kwargs

    @property
    def hardware_id(self) -> str:
        """'<interface>:<channel>', as the diagnostics report it."""
        return f'{self.interface}:{self.channel}'
