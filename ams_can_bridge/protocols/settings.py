# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Device configuration from the layout table: one mechanism for every ZEVA settings frame.

A setting is a :class:`Signal` row with a ``field`` and what its parameter declares (range,
step = scale, unit, description, kind, enum codes, a ``sentinel`` end: EVMS3 1210 A = off).
:class:`Settings` derives from the rows the ConfigFields, the check of a value (nothing
clamped or rounded), the payloads and the values of a payload (a raw value the device could
not have sent is malformed). Rows without a field are bits the protocol module handles itself.
"""
from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

from ams_can_bridge.errors import EncodeRangeError, LayoutError
from ams_can_bridge.protocols.common import ConfigField
from ams_can_bridge.protocols.layout import check_flag, check_value, Layout, LITTLE, Signal


def setting(name: str, byte: int, field: str, low: float | None, high: float | None,
            unit: str, description: str, kind: type = int, scale: float = 1,
            offset: float = 0, length: int = 8, bit: int = 0,
            sentinel: tuple[float, str] | None = None, lookup: tuple | None = None) -> Signal:
    """Return the row of a little-endian setting in byte (bit) of its frame (bool: a flag)."""
    return Signal(name, 8 * byte + bit, length, LITTLE, False, scale, offset, low, high, unit,
                  field, flag=kind is bool, lookup=lookup, description=description, kind=kind,
                  sentinel=sentinel)


def raw_fault(s: Signal, raw: int, value: Any) -> str:
    """Say which raw byte is impossible (the EVMS3 wording): 'name raw 17 outside 8..16'."""
    if s.flag:
        return f'{s.field} raw {raw}, expected 0 or 1'
    low, high = raw_bounds(s)
    return f'{s.field} raw {raw} outside {low}..{high}'


def raw_bounds(s: Signal) -> tuple[int, int]:
    """Return the raw values a setting row allows: its physical range, or 0..1, or its codes."""
    if s.flag:
        return 0, 1
    if s.lookup is not None:
        return 0, len(s.lookup) - 1
    return s.raw_limits()


class Settings:
    """The settings of one device: its configuration frames, each a Layout of setting rows."""

    def __init__(self, layouts: Sequence[Layout],
                 fault: Callable[[Signal, int, Any], str] = raw_fault,
                 ranged: bool = True) -> None:
        """
        Keep the frames' rows by field; fault(row, raw, value) words a malformed byte.

        ranged: descriptions end in the range (and sentinel), '(10..1210 A; 1210 = off)', as
        the ZEVA Monitor's settings read; else the description is the row's own text.
        """
        self.layouts = tuple(layouts)
        self.rows = {s.field: s for layout in self.layouts for s in layout.signals if s.field}
        # Decoding: the generated raw decoder of each frame's settings, and per setting its
        # raw range and its value of every raw value (a setting is a byte or less).
        self._raw = tuple(layout.decoder(*(s.name for s in layout.signals if s.field), raw=True)
                          for layout in self.layouts)
        self._plans = tuple(tuple(
            (s.field, *raw_bounds(s), self._values(s)) for s in layout.signals
            if s.field) for layout in self.layouts)
        self._fault = fault
        self._ranged = ranged

    # --- what the parameters declare ----------------------------------------------------
    def field(self, name: str) -> ConfigField:
        """Return the ConfigField of one setting, derived from its row."""
        s = self.rows[name]
        if s.flag:
            return ConfigField(name, bool, description=s.description)
        if s.lookup is not None:
            return ConfigField(name, s.kind or int, min(s.lookup), max(s.lookup), None,
                               s.unit, s.description)
        low, high = s.bounds()
        if s.kind is int:
            low, high = int(low), int(high)
        description = s.description
        if self._ranged:
            ends = f'{low:g}..{high:g} {s.unit}'.rstrip()
            if s.sentinel is not None:
                ends += f'; {s.sentinel[0]:g} = {s.sentinel[1]}'
            description += f' ({ends})'
        return ConfigField(name, s.kind or float, low, high, abs(s.scale), s.unit, description)

    def sentinels(self) -> dict[str, tuple[float, str]]:
        """Return name -> (value, word) of the settings whose range end is a word (off, never)."""
        return {name: s.sentinel for name, s in self.rows.items() if s.sentinel is not None}

    # --- encode -------------------------------------------------------------------------
    def check(self, name: str, value: Any) -> Any:
        """Validate one value; return it normalized (bool, int or float), EncodeRangeError."""
        s = self.rows.get(name)
        if s is None:
            raise EncodeRangeError(name, value, 'one of ' + ', '.join(self.rows))
        if s.flag:
            return bool(check_flag(name, value))
        if s.lookup is not None:
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or value not in s.lookup:
                raise EncodeRangeError(name, value, s.description)  # it names the codes
            return (s.kind or int)(value)
        low, high = s.bounds()
        number = check_value(name, value, low, high, abs(s.scale), s.unit)
        return int(round(number)) if s.kind is int else round(float(number), 6)

    def raw(self, name: str, value: Any) -> int:
        """Return the wire value of one setting (checked: EncodeRangeError)."""
        s = self.rows[name]
        value = self.check(name, value)
        if s.lookup is not None:
            return s.lookup.index(value)
        return int(value) if s.flag else round((value - s.offset) / s.scale)

    def payload(self, k: int, values: Mapping[str, Any] | Any,
                raws: Mapping[str, int] | None = None) -> bytes:
        """
        Return frame k's bytes: each setting of values (a mapping or an object) checked.

        raws: raw values of the rows without a field, by signal name (0 when not given).
        """
        layout = self.layouts[k]
        get = values.get if isinstance(values, Mapping) else (
            lambda name: getattr(values, name))
        n = 0
        for s in layout.signals:
            raw = self.raw(s.field, get(s.field)) if s.field else (raws or {}).get(s.name, 0)
            n |= raw << s.lsb(layout.length)
        return n.to_bytes(layout.length, 'little')

    # --- decode -------------------------------------------------------------------------
    def decode(self, k: int, data: bytes,
               fail: Callable[[str], Exception] | None = None) -> dict[str, Any]:
        """
        Return the settings of frame k's payload by name (the caller checked its length).

        fail(why) is raised for a raw value outside the row's range: the device never sends
        one, so the frame is not a configuration to trust. fail=None: the values as on the
        wire, unchecked (a simulator clamps them, as the device does).
        """
        values: dict[str, Any] = {}
        for (name, low, high, value), raw in zip(self._plans[k], self._raw[k](data)):
            if not low <= raw <= high and fail is not None:
                raise fail(self._fault(self.rows[name], raw, value[raw]))
            values[name] = value[raw]
        return values

    @staticmethod
    def _values(s: Signal) -> tuple:
        """Return the value of each raw value of a setting in its kind (exact decimals)."""
        if s.length > 8:
            raise LayoutError(f'{s.name}: a setting is a byte or less, not {s.length} bits')
        raws = range(1 << s.length)
        if s.flag:
            return tuple(raw != 0 for raw in raws)
        if s.lookup is not None:  # None past the enum codes
            return tuple(s.lookup) + (None,) * (len(raws) - len(s.lookup))
        values = [raw * s.scale + s.offset for raw in raws]
        return tuple(int(round(v)) if s.kind is int else round(v, 6) for v in values)

    def fields(self) -> tuple[ConfigField, ...]:
        """Return the ConfigField of every setting, in frame order."""
        return tuple(self.field(name) for name in self.rows)
