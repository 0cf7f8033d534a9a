"""
Device configuration from the layout table: one mechanism for every ZEVA settings frame.

A configuration frame is a :class:`Layout` whose :class:`Signal` rows name a setting
(``field``) and carry what the parameters declare: range, step (the scale), unit,
``description``, ``kind`` (int or float; a ``flag`` is a bool), enum codes (``lookup``) and a
``sentinel`` end (EVMS3: 1210 A = off). :class:`Settings` derives from them the ConfigFields
(``fields``), the check of one value (:func:`check_value`: EncodeRangeError, nothing clamped
or rounded), a frame's payload and a frame's values (``decode``: a raw value the device could
not have sent makes the frame malformed). Rows without a field (the EVMS3 balance byte, a
charge voltage's 9th bit) are bits the protocol module reads and writes itself.
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
    """
    Return the row of a little-endian setting in byte (bit) of its frame.

    The columns a settings table reads best in: signal name (the DBC's), byte, field, physical
    range and unit, description; kind bool makes a 0/1 flag (range 0..1).
    """
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
        if s.flag:
            return int(value)
        if s.lookup is not None:
            return s.lookup.index(value)
        return round((value - s.offset) / s.scale)

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
    @staticmethod
    def physical(s: Signal, raw: int) -> Any:
        """Return a setting's value of one raw value, in its kind (exact decimals)."""
        if s.flag:
            return bool(raw)
        if s.lookup is not None:
            return s.lookup[raw]
        value = raw * s.scale + s.offset
        return int(round(value)) if s.kind is int else round(value, 6)

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

    def _values(self, s: Signal) -> tuple:
        """Return the value of each raw value of a setting (None past its enum codes)."""
        if s.length > 8:
            raise LayoutError(f'{s.name}: a setting is a byte or less, not {s.length} bits')
        return tuple(None if s.lookup is not None and raw >= len(s.lookup)
                     else self.physical(s, raw) for raw in range(1 << s.length))

    def fields(self) -> tuple[ConfigField, ...]:
        """Return the ConfigField of every setting, in frame order."""
        return tuple(self.field(name) for name in self.rows)
