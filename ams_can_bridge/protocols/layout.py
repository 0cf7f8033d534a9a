# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
One table format for every wire layout, compiled once into straight-line code.

A protocol states each message once, as a :class:`Layout` of :class:`Signal` rows; from it come
``decoder()`` and ``encoder()`` (generated functions, no loop and no call per signal) and
``check_dbc()`` (the table against msg_defs/). doc/architecture.md, "Protocols", says how.
:func:`check_value` is the one number / range / step validator of the package.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any, Callable

from ams_can_bridge.errors import EncodeRangeError, LayoutError, ProtocolError

BIG = 'big_endian'
LITTLE = 'little_endian'


def check_value(field: str, value: Any, low: float, high: float, step: float | None = None,
                unit: str = '', integer: bool = False) -> Any:
    """
    Return value if it is a number in low..high (on the step grid from low), else raise.

    Float noise is forgiven: tolerance() at the ends (255 * 0.02 = 5.1000000000000005 is 5.1,
    and comes back as 5.1), a millionth of a step on the grid. bool, NaN and non-numbers are
    refused; integer=True also refuses a fraction (3.0 is fine, YAML spells numbers either
    way) and returns an int.
    """
    suffix = f' {unit}' if unit else ''
    allowed = f'{low:g}..{high:g}{suffix}' + (
        f' in steps of {step:g}{suffix}' if step and step != 1 else
        ', a whole number' if integer or step == 1 else '')
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise EncodeRangeError(field, value, f'a number {allowed}')
    if value != value:  # NaN
        raise EncodeRangeError(field, value, allowed)
    if not low <= value <= high:
        tol = tolerance(low, high, step, integer)
        if low - tol <= value < low:
            value = low
        elif high < value <= high + tol:
            value = high
        else:
            raise EncodeRangeError(field, value, allowed)
    if step:
        n = (value - low) / step
        if abs(n - round(n)) > 1e-6:
            raise EncodeRangeError(field, value, allowed)
    if integer or step == 1:
        if isinstance(value, float) and not value.is_integer():
            raise EncodeRangeError(field, value, allowed)
        return int(value)
    return value


def tolerance(low: float, high: float, step: float | None = None,
              integer: bool = False) -> float:
    """
    Return the float noise check_value forgives at the ends of low..high.

    A billionth of the step, else of the range's larger end (at least 1): the one rule for
    every range check of the package, also where a generated decoder compares inline.
    """
    return 1e-9 * (step or (1 if integer else max(1.0, abs(low), abs(high))))


def check_flag(field: str, value: Any) -> int:
    """Return 0 or 1 for a bool (or 0/1); anything else is refused."""
    if value not in (0, 1) or not isinstance(value, (bool, int)):
        raise EncodeRangeError(field, value, 'True/False (or 0/1)')
    return int(value)


class BadValue(ProtocolError):
    """A value a row's ``check`` refuses; the codec raises MalformedFrameError (it has the ID)."""


class _Known(dict[int, Any]):
    """Raw value -> enum member of a checked lookup; an unknown raw value is a BadValue."""

    def __init__(self, s: Signal) -> None:
        super().__init__((raw, m) for raw, m in enumerate(s.lookup or ()) if m is not None)
        self.check = s.check
        self.raws = {m: raw for raw, m in self.items()}

    def __missing__(self, raw: int) -> Any:
        raise BadValue(self.check.format(value=raw, low=min(self), high=max(self)))

    def encode(self, field: str, value: Any) -> int:
        """Return the raw value of a member (or of its int); EncodeRangeError else."""
        if isinstance(value, int) and not isinstance(value, bool) and value in self.raws:
            return self.raws[value]
        names = ', '.join(f'{getattr(m, "name", m)}={raw}' for raw, m in self.items())
        kind = type(next(iter(self.values()))).__name__
        article = 'an' if kind[0] in 'AEIOU' else 'a'  # an AmsState, an Evms3Error
        raise EncodeRangeError(field, value, f'{article} {kind} value ({names})')


@dataclass(frozen=True)
class Signal:
    """One signal of a message, as a DBC ``SG_`` line states it."""

    name: str
    start: int  # DBC numbering: LSB (little-endian) or MSB in sawtooth order (big-endian)
    length: int
    byte_order: str = BIG
    signed: bool = False
    scale: float = 1
    offset: float = 0
    low: float | None = None  # physical range; None: what the bits can carry
    high: float | None = None
    unit: str = ''
    field: str = ''  # the reading's name for it in error messages (default: name)
    flag: bool = False  # a 1-bit signal decoded as a bool (True/False or 0/1 to encode)
    invalid: int | None = None  # raw value meaning "not available": None both ways
    # decode only: raw value -> reading value (an enum member, None); IndexError past its end
    lookup: tuple | None = None
    # A configuration setting (protocols/settings.py derives its ConfigField from the row):
    # what it means, its physical type (int or float; a flag is a bool) and a range end that
    # the device reads as a word (EVMS3: warn current 1210 A = 'off'). No effect on the code.
    description: str = ''
    kind: type | None = None
    sentinel: tuple[float, str] | None = None
    # A rule of the protocol (not of the bits): decoding refuses a value outside low..high
    # (with a lookup: a raw value without a member, low..high then the known raw values),
    # raising BadValue with this text formatted with value, low and high ('bank ID {value}
    # (allowed {low}..{high})'); encoding a lookup then takes only a member (or its int).
    check: str = ''

    def raw_range(self) -> tuple[int, int]:
        """Return the raw values the bits carry, without the "not available" marker."""
        low = -(1 << (self.length - 1)) if self.signed else 0
        high = (1 << (self.length - 1)) - 1 if self.signed else (1 << self.length) - 1
        return low + (self.invalid == low), high - (self.invalid == high)

    def bounds(self) -> tuple[float, float]:
        """Return the physical range: the stated one, else what the raw bits can carry."""
        lo_raw, hi_raw = self.raw_range()
        ends = sorted((lo_raw * self.scale + self.offset, hi_raw * self.scale + self.offset))
        return (ends[0] if self.low is None else self.low,
                ends[1] if self.high is None else self.high)

    def raw_limits(self) -> tuple[int, int]:
        """Return the raw values whose physical value lies in bounds() (a check's range)."""
        ends = sorted((b - self.offset) / self.scale for b in self.bounds())
        return math.ceil(ends[0] - 1e-9), math.floor(ends[1] + 1e-9)

    def lsb(self, length: int) -> int:
        """Return the bit of its LSB in the frame read as one integer in its byte order."""
        if self.byte_order == LITTLE:
            return self.start
        msb = (self.start // 8) * 8 + (7 - self.start % 8)
        return 8 * length - 1 - (msb + self.length - 1)


@dataclass(frozen=True)
class Layout:
    """
    One message: its name, DLC and signals; ``divide`` writes a scale 1/n as ``raw / n``.

    ``divide`` is for vendors whose firmware divides (EVMS3: 1234 -> 123.4 V exactly, where
    1234 * 0.1 is 123.4000...01); without it the values are exactly what cantools computes.
    """

    name: str
    length: int
    signals: tuple[Signal, ...]
    divide: bool = False

    @classmethod
    def from_dbc(cls, message: Any, divide: bool = False) -> Layout:
        """Build the layout of a cantools message (integer signals, no multiplexing)."""
        return cls(message.name, message.length, tuple(Signal(
            s.name, s.start, s.length, s.byte_order, bool(s.is_signed), s.scale, s.offset,
            s.minimum, s.maximum, s.unit or '') for s in message.signals), divide)

    def check_dbc(self, message: Any, dbc: str, codec: str) -> None:
        """Raise LayoutError unless the DBC message has exactly these bits, scales and DLC."""
        def bits(layout: Layout) -> tuple:
            return layout.length, sorted((s.name, s.start, s.length, s.byte_order, s.signed,
                                          float(s.scale), float(s.offset))
                                         for s in layout.signals)
        got = bits(Layout.from_dbc(message)) + (any(s.is_float for s in message.signals),)
        if got != bits(self) + (False,):
            raise LayoutError(f'{dbc} {message.name} does not match the {codec} codec '
                              f'layout: {got}')

    # --- code generation --------------------------------------------------------------------
    def raw_expression(self, s: Signal) -> str:
        """Return a Python expression of a signal's raw value, as cheap as hand code."""
        if s.byte_order == BIG:
            msb = (s.start // 8) * 8 + (7 - s.start % 8)  # bit from the frame's first MSB
            first, last = msb // 8, (msb + s.length - 1) // 8
            shift, lsb_byte = 7 - (msb + s.length - 1) % 8, last
        else:
            first, last = s.start // 8, (s.start + s.length - 1) // 8
            shift, lsb_byte = s.start % 8, first
        # the byte of the LSB as it is, each byte further from it 8 bits higher
        expr = ' | '.join(f'data[{k}] << {8 * abs(k - lsb_byte)}' if k != lsb_byte
                          else f'data[{k}]' for k in range(first, last + 1))
        if shift:
            expr = f'({expr}) >> {shift}'
        if shift or s.length != 8 * (last - first + 1):
            expr = f'({expr}) & {(1 << s.length) - 1:#x}'
        if s.signed:
            half = 1 << (s.length - 1)
            expr = f'(({expr}) ^ {half:#x}) - {half:#x}'
        return expr

    def value_expression(self, s: Signal, raw_only: bool = False,
                         tables: dict[str, Any] | None = None) -> str:
        """
        Return the expression of a signal's value as decoder() computes it.

        Without tables (code compiled beside the table's own) a lookup stays raw, a check is
        not made and a scaled byte is computed inline.
        """
        raw = self.raw_expression(s)
        if s.flag and not raw_only:
            return f'({raw}) != 0'
        if s.lookup is not None and not raw_only and tables is not None:
            name = f'T{len(tables)}'
            tables[name] = _Known(s) if s.check else s.lookup
            return f'{name}[{raw}]'
        plain = raw_only or (s.scale == 1 and s.offset == 0)
        var = f'r_{s.start}_{s.length}'  # the raw value, read once (:=) where tested
        value = var if plain else self.scaled_expression(s, var)
        if s.check and tables is not None:
            # The range test is on the raw integer (exact); the message shows the value.
            # A bound the bits cannot pass is not tested (every AMS cell frame's group ID).
            name, (lo, hi), carried = f'B{len(tables)}', s.raw_limits(), s.raw_range()
            tested = var if s.invalid is not None else f'({var} := {raw})'
            test = (f'{lo} <= ' if lo > carried[0] else '') + tested + (
                f' <= {hi}' if hi < carried[1] else '')
            if test != tested:
                tables[name] = functools.partial(self._refuse, s, self._scale_function(s))
                value = f'{value} if {test} else {name}({var})'
                if s.invalid is None:
                    return f'({value})'
        if s.invalid is not None:
            return f'(None if ({var} := {raw}) == {s.invalid} else {value})'
        if plain:
            return raw
        if tables is not None and s.length <= 8 and not s.signed:
            # A byte or less: look the scaled value up (no float built per frame), each
            # entry computed by the very expression used otherwise.
            scale = self._scale_function(s)
            name = f'T{len(tables)}'
            tables[name] = tuple(scale(r) for r in range(1 << s.length))
            return f'{name}[{raw}]'
        return self.scaled_expression(s, raw)

    def _scale_function(self, s: Signal) -> Callable[[int], Any]:
        return compile_function(f'def f(r):\n    return {self.scaled_expression(s, "r")}\n',
                                self.name, 'f')

    @staticmethod
    def _refuse(s: Signal, scale: Callable[[int], Any], raw: int) -> Any:
        low, high = s.bounds()
        raise BadValue(s.check.format(value=scale(raw), low=low, high=high))

    def scaled_expression(self, s: Signal, raw: str) -> str:
        """Return the physical value of a raw expression (divide: as the vendor computes it)."""
        divisor = 1 / s.scale
        if self.divide and s.scale == 1 and s.offset == round(s.offset):
            return f'({raw}) + {round(s.offset)}'  # whole numbers stay int (raw 65 -> 25 degC)
        if self.divide and abs(divisor - round(divisor)) < 1e-9:
            shift = s.offset * round(divisor)  # (raw - 8388608) / 1000, as the vendor
            if shift == round(shift):
                return f'(({raw}) + {round(shift)}) / {round(divisor)}'
            scaled = f'({raw}) / {round(divisor)}'
        else:
            scaled = f'({raw}) * {s.scale!r}'
        return scaled if s.offset == 0 else f'{scaled} + {s.offset!r}'

    def decoder(self, *names: str, raw: bool = False, into: Callable | None = None,
                head: Callable | None = None, pack: int = 0,
                tail: int = 0) -> Callable[..., Any]:
        """
        Return ``decode(data)``: the physical (or raw) values of names (default all).

        As a tuple, or ``into(values...)`` (a reading class), or ``into(head(data), values...)``
        (a part decoded elsewhere first, as a cached status word): one call per frame.
        pack=n: ``decode(data, a1..an)`` returns ``into(a1..an, (values...))``, values as one
        tuple after n arguments of the caller (as a module and a first cell).
        tail=n: the last n values as one tuple (a series of cells after their bank and group).
        """
        by_name = {s.name: s for s in self.signals}
        signals = [by_name[n] for n in names] if names else self.signals
        tables: dict[str, Any] = {}
        values = [self.value_expression(s, raw, tables) for s in signals]
        if tail:
            values[-tail:] = [f'({", ".join(values[-tail:])},)']
        body = ', '.join(values)
        args = ''.join(f', a{k}' for k in range(pack))
        if pack:
            body = f'{args[2:]}, ({body},)'
        result = (f'into(head(data), {body})' if head else f'into({body})') if into \
            else f'({body},)'
        return compile_function(f'def decode(data{args}):\n    return {result}\n', self.name,
                                'decode', {'into': into, 'head': head, **tables})

    def replace(self, name: str, **changes: Any) -> Layout:
        """Return this layout with one signal changed (a variant the DBC cannot describe)."""
        return dataclasses.replace(self, signals=tuple(
            dataclasses.replace(s, **changes) if s.name == name else s for s in self.signals))

    def encoder(self, exact: bool = True) -> Callable[..., bytes]:
        """
        Return ``encode(*values) -> bytes``: each value checked, scaled, packed.

        exact (commands, configuration): a value off the signal's step is refused. exact=False
        (telemetry a simulator sends): the range is checked and the value rounded to the step.
        """
        args = [f'v{i}' for i in range(len(self.signals))]
        lines = [f'def encode({", ".join(args)}):', '    n = 0']
        scope: dict[str, Any] = {'check': check_value, 'flag': check_flag}
        for i, s in enumerate(self.signals):
            low, high = s.bounds()
            field = s.field or s.name
            integer = exact and s.scale == 1 and s.offset == 0 and float(low).is_integer()
            step = None if integer or not exact else abs(s.scale)
            scope[f'S{i}'] = (low, high, step, s.unit, integer)
            checked = f'check({field!r}, v{i}, *S{i})'
            if s.flag:  # 0/1 or a bool; 2 or 'yes' is refused
                checked = f'flag({field!r}, v{i})'
            if s.check and s.lookup is not None:  # a member of the lookup, nothing else
                scope[f'S{i}'] = _Known(s)
                checked = f'S{i}.encode({field!r}, v{i})'
            raw = checked if integer else f'round(({checked} - {s.offset!r}) / {s.scale!r})'
            if not exact and s.scale == 1 and s.offset == 0:
                raw = f'round({checked})'
            if s.invalid is not None:  # None: the marker
                raw = f'{s.invalid} if v{i} is None else {raw}'
            if s.signed:
                raw = f'({raw}) & {(1 << s.length) - 1:#x}'
            # Little-endian signals fill the low half of n, big-endian ones a high half read
            # big-endian; both halves are folded into one frame below.
            half = 0 if s.byte_order == LITTLE else 8 * self.length
            lines.append(f'    n |= ({raw}) << {s.lsb(self.length) + half}')
        lines += [f'    lo = (n & {(1 << 8 * self.length) - 1:#x}).to_bytes('
                  f"{self.length}, 'little')",
                  f"    hi = (n >> {8 * self.length}).to_bytes({self.length}, 'big')",
                  '    return bytes(a | b for a, b in zip(lo, hi))']
        return compile_function('\n'.join(lines) + '\n', self.name, 'encode', scope)


def compile_function(source: str, name: str, function: str,
                     scope: dict[str, Any] | None = None) -> Callable:
    """Compile generated code: the tables' own and a protocol's (its per-ID fast path)."""
    scope = dict(scope or {})
    exec(compile(source, f'<layout {name}>', 'exec'), scope)  # noqa: S102 (our own table)
    compiled: Callable = scope[function]
    return compiled
