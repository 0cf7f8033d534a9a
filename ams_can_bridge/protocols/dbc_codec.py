# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A team's own DBC, compiled: frames -> tuples of physical values, checked against [min|max].

Each message becomes one generated function (the shifts and masks of protocols/layout.py;
cantools' Message.decode, the reference, builds a dict per frame at several microseconds)
returning a tuple in the order of ``CompiledMessage.signals``: a value out of range is NaN
with its index reported, a multiplexed signal outside the frame's branch None. Float signals
and nested multiplexers fall back to cantools, into the same tuple. doc/protocols.md section
8 holds what the package decides on top of a DBC.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from cantools.database.can import Message

from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.layout import compile_function, Layout, tolerance

NAN = math.nan


@dataclass(frozen=True)
class SignalInfo:
    """What the device needs of one DBC signal besides its bits."""

    name: str
    unit: str
    minimum: float | None
    maximum: float | None
    scale: float
    offset: float
    choices: dict[int, str]  # raw value -> name (VAL_)
    mux_ids: tuple[int, ...] | None  # multiplexer values carrying it (None: every frame)
    is_multiplexer: bool
    length: int = 0  # bits
    is_signed: bool = False

    def physical(self, raw: int) -> float:
        """Return the physical value of a raw value (raw * scale + offset, as cantools)."""
        return raw * self.scale + self.offset


@dataclass
class CompiledMessage:
    """One DBC message, ready to decode: its signals in a fixed order and a decoder."""

    name: str
    frame_id: int
    is_extended_id: bool
    length: int
    signals: tuple[SignalInfo, ...]
    index: dict[str, int]  # signal name -> position in the decoded tuple
    mux_index: int | None  # position of the (single-level) multiplexer signal, if any
    compiled: bool  # False: decoded through cantools (floats, nested multiplexers)
    decode_values: Callable[[bytes], tuple[tuple, tuple[int, ...]]] = field(repr=False)

    def decode(self, data: bytes) -> tuple[tuple, tuple[int, ...]]:
        """Return (values, indices out of range); MalformedFrameError if too short."""
        if len(data) < self.length:
            raise MalformedFrameError(self.frame_id, data,
                                      f'{self.name}: DLC {len(data)}, expected {self.length}')
        return self.decode_values(data)


def closest(name: str, names: Sequence[str], n: int = 3) -> str:
    """Say which known names come closest to a misspelt one (for error messages)."""
    near = difflib.get_close_matches(name, list(names), n=n, cutoff=0.5)
    if not near:
        near = [k for k in names if k.lower().startswith(name[:3].lower())][:n]
    return ('; closest: ' + ', '.join(near)) if near else ''


def _info(message: Message) -> tuple[SignalInfo, ...]:
    return tuple(SignalInfo(
        name=s.name, unit=s.unit or '', minimum=s.minimum, maximum=s.maximum,
        scale=float(s.scale), offset=float(s.offset),
        choices={int(k): str(v) for k, v in (s.choices or {}).items()},
        mux_ids=tuple(s.multiplexer_ids) if s.multiplexer_ids else None,
        is_multiplexer=bool(s.is_multiplexer), length=s.length,
        is_signed=bool(s.is_signed)) for s in message.signals)


def _limits(info: SignalInfo, bound: tuple[float, float] | None = None
            ) -> tuple[float, float]:
    """
    Return the DBC's [min|max] widened by layout.tolerance (inf where not stated).

    ``bound``: what the field the signal is mapped to can be (protocols.dbc_mapping.plan
    FIELD_BOUNDS, in the signal's DBC unit): the two ranges intersected.
    """
    # float noise: 0.1 * 51 is 5.1000000000000005, still inside a DBC range [0|5.1]
    ends = [float(e) for e in (info.minimum, info.maximum) if e is not None]
    tol = tolerance(min(ends, default=0), max(ends, default=0))
    low = -math.inf if info.minimum is None else info.minimum - tol
    high = math.inf if info.maximum is None else info.maximum + tol
    if bound is not None:
        tol = tolerance(*bound)
        low, high = max(low, bound[0] - tol), min(high, bound[1] + tol)
    return low, high


def in_range(info: SignalInfo, value: float) -> bool:
    """Tell whether a physical value lies in the signal's DBC [min|max] (as the decoder)."""
    low, high = _limits(info)
    return low <= value <= high


def _malformed(message: Message, data: bytes, mux: object) -> MalformedFrameError:
    return MalformedFrameError(message.frame_id, data,
                               f'{message.name}: multiplexer value {mux} not in the DBC')


def _generate(message: Message, infos: tuple[SignalInfo, ...],
              bounds: dict[int, tuple[float, float]]) -> Callable | None:
    """Build the decoder of a message; None when cantools must do it."""
    if any(s.is_float for s in message.signals):
        return None
    muxes = [i for i, info in enumerate(infos) if info.is_multiplexer]
    if len(muxes) > 1 or any(infos[i].mux_ids for i in muxes):
        return None  # nested multiplexing
    # The bits and scaling as protocols/layout.py reads them (data[k], shifts and masks).
    layout = Layout.from_dbc(message)
    scope: dict[str, Any] = {'NAN': NAN, 'inf': math.inf, 'malformed': _malformed,
                             'message': message}
    lines = ['def decode(data):', '    bad = []']

    def value(i: int, indent: str) -> None:
        s = layout.signals[i]
        lines.append(f'{indent}v{i} = {layout.value_expression(s)}')
        low, high = _limits(infos[i], bounds.get(i))
        carried = sorted(r * s.scale + s.offset for r in s.raw_range())
        if not low <= carried[0] <= carried[1] <= high:  # else the bits cannot leave it
            lines.extend([f'{indent}if not {low!r} <= v{i} <= {high!r}:',  # constants inline
                          f'{indent}    v{i} = NAN; bad.append({i})'])
    branches: dict[int, list[int]] = {}
    for i, info in enumerate(infos):
        for mux_id in info.mux_ids or ():
            branches.setdefault(mux_id, []).append(i)
        if not info.mux_ids:  # in every frame (the multiplexer too)
            value(i, '    ')
    if muxes:
        lines.append(f'    mux = {layout.raw_expression(layout.signals[muxes[0]])}')
    if branches:
        muxed = sorted({i for members in branches.values() for i in members})
        lines.append('    ' + ' = '.join(f'v{i}' for i in muxed) + ' = None')
        for n, (mux_id, members) in enumerate(sorted(branches.items())):
            lines.append(f'    {"elif" if n else "if"} mux == {mux_id}:')
            for i in members:
                value(i, '        ')
        lines += ['    else:', '        raise malformed(message, data, mux)']
    names = ''.join(f'v{i}, ' for i in range(len(infos)))  # () for a message of no signal
    lines.append(f'    return ({names}), bad')
    return compile_function('\n'.join(lines) + '\n', f'dbc {message.name}', 'decode', scope)


def _cantools_decoder(message: Message, infos: tuple[SignalInfo, ...],
                      bounds: dict[int, tuple[float, float]]) -> Callable:
    """
    Decode through cantools (the slow path), into the same tuple and range report.

    A float signal can carry inf and NaN: neither is a value (outside any range).
    """
    names = [s.name for s in message.signals]
    limits = [_limits(info, bounds.get(i)) for i, info in enumerate(infos)]

    def decode(data: bytes) -> tuple[tuple, tuple[int, ...]]:
        try:
            # a plain message (not a container): a dict of numbers, choices not decoded
            decoded: dict[str, Any] = message.decode(  # type: ignore[assignment]
                bytes(data[:message.length]), decode_choices=False)
        except Exception as exc:  # cantools' own errors (unknown multiplexer id, ...)
            raise _malformed(message, data, exc) from None
        values, bad = [], []
        for i, name in enumerate(names):
            value = decoded.get(name)
            if value is not None:
                value = float(value)
                if not limits[i][0] <= value <= limits[i][1] or not math.isfinite(value):
                    value = NAN
                    bad.append(i)
            values.append(value)
        return tuple(values), tuple(bad)
    return decode


def compile_message(message: Message,
                    bounds: dict[int, tuple[float, float]] | None = None) -> CompiledMessage:
    """
    Compile one cantools message.

    ``bounds``: signal index -> (low, high) physical values the signal may also not leave
    (the plausibility of the field it is mapped to); a value beyond them is reported as one
    out of its range.
    """
    infos = _info(message)
    bounds = bounds or {}
    decoder = _generate(message, infos, bounds)
    muxes = [i for i, info in enumerate(infos) if info.is_multiplexer]
    return CompiledMessage(
        name=message.name, frame_id=message.frame_id,
        is_extended_id=bool(message.is_extended_frame), length=message.length,
        signals=infos, index={info.name: i for i, info in enumerate(infos)},
        mux_index=muxes[0] if len(muxes) == 1 else None, compiled=decoder is not None,
        decode_values=decoder or _cantools_decoder(message, infos, bounds))


def encode(message: Message, values: dict[str, float]) -> bytes:
    """Encode physical values through cantools (the simulator's path), strictly in range."""
    return message.encode(values, scaling=True, strict=True)
