"""
Terminal view of the demo: plain data in, text out (no ROS, no curses).

The demo fills a ``View`` from the bridge's real ROS topics; ``render`` turns it into aligned
text with units, NaN shown as a dash (or 'n/a' without Unicode), and the diagnostics level in
colour when the output is a terminal. Keeping the renderer free of ROS lets it be tested with
known data and reused by anything that wants a one-screen summary of a pack.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

NAN = math.nan

RESET = '\033[0m'
BOLD = '\033[1m'
DIM = '\033[2m'
COLOURS = {
    'OK': '\033[32m',       # green
    'WARN': '\033[33m',     # yellow
    'ERROR': '\033[31;1m',  # bold red
    'STALE': '\033[35m',    # magenta: old numbers, not a device error
}
# States worth a colour of their own: the AMS walking to DRIVE is what the demo is about.
STATE_COLOURS = {
    'DRIVE': '\033[32;1m', 'TS_ACTIVE': '\033[36m', 'PRECHARGING': '\033[33m',
    'SC_ENABLED': '\033[34m', 'ERROR': '\033[31;1m', 'CHARGE_ERROR': '\033[31;1m',
}
LEVELS = ('OK', 'WARN', 'ERROR', 'STALE')


@dataclass
class DeviceRow:
    """What the view shows of one device instance (NaN = not known yet)."""

    name: str
    type: str
    state: str = ''
    voltage: float = NAN       # V
    current: float = NAN       # A, negative = discharging
    percentage: float = NAN    # 0..1
    cell_min: float = NAN      # V
    cell_max: float = NAN      # V
    temperature: float = NAN   # degC
    level: str = ''            # OK / WARN / ERROR / STALE, '' before the first diagnostics
    message: str = ''          # the diagnostics one-line summary


@dataclass
class View:
    """Everything on one screen of the demo."""

    bus: str = ''
    uptime_s: float = 0.0
    frames_in: int | None = None
    frames_out: int | None = None
    bus_state: str = ''
    bus_level: str = ''
    rows: list[DeviceRow] = field(default_factory=list)
    last_command: str = ''
    last_answer: str = ''
    notes: list[str] = field(default_factory=list)


def level_name(level: int | bytes | str | None) -> str:
    """Return 'OK'/'WARN'/'ERROR'/'STALE' for a diagnostics level byte, int or name."""
    if isinstance(level, (bytes, bytearray)):
        level = level[0] if level else None
    if isinstance(level, str):
        return level.upper()
    if level is None:
        return ''
    return LEVELS[level] if 0 <= level < len(LEVELS) else f'LEVEL {level}'


def cell_range(cells: list[float] | tuple[float, ...]) -> tuple[float, float]:
    """Return (min, max) of the known cell voltages; (NaN, NaN) when none is known yet."""
    known = [v for v in cells if isinstance(v, (int, float)) and math.isfinite(v)]
    if not known:
        return NAN, NAN
    return min(known), max(known)


def fmt_value(value: float | None, unit: str, digits: int, missing: str) -> str:
    """Format a number with its unit, or the missing marker for None/NaN/inf."""
    if value is None or not isinstance(value, (int, float)) or not math.isfinite(value):
        return missing
    if round(value, digits) == 0:
        value = 0.0  # '-0.0 A' would suggest a direction where there is none
    return f'{value:.{digits}f} {unit}'.rstrip()


def fmt_uptime(seconds: float) -> str:
    """Return H:MM:SS for a duration in seconds."""
    seconds = max(0, int(seconds))
    return f'{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}'


def _paint(text: str, code: str | None, colour: bool) -> str:
    """Wrap already padded text in an ANSI colour (padding first keeps columns aligned)."""
    if not colour or not code:
        return text
    return f'{code}{text}{RESET}'


# (title, width, right-aligned) of each column; widths fit the largest realistic values
# ('PRECHARGING', '-109.1 A', '100.0 %', '3.900..3.920 V', '-25.0 °C') and the whole row
# fits a terminal of 80 columns (WIDTH). The device type is not shown: the demo's device
# names are their types.
COLUMNS = (
    ('DEVICE', 6, False), ('STATE', 11, False),
    ('VOLTAGE', 7, True), ('CURRENT', 8, True), ('SOC', 7, True),
    ('CELLS', 14, True), ('TEMP', 8, True), ('DIAG', 5, False),
)
WIDTH = 80  # columns of a default terminal: every line of the view fits


def fmt_cells(low: float, high: float, missing: str) -> str:
    """Format the cell voltage range as '3.900..3.920 V', or the missing marker."""
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (low, high)):
        return missing
    return f'{low:.3f}..{high:.3f} V'


def _cells(row: DeviceRow, missing: str, degree: str) -> list[str]:
    pct = row.percentage * 100.0 if isinstance(row.percentage, (int, float)) else NAN
    return [
        row.name, row.state or missing,
        fmt_value(row.voltage, 'V', 1, missing),
        fmt_value(row.current, 'A', 1, missing),
        fmt_value(pct, '%', 1, missing),
        fmt_cells(row.cell_min, row.cell_max, missing),
        fmt_value(row.temperature, degree, 1, missing),
        row.level or missing,
    ]


def _line(texts: list[str], colours: list[str | None], colour: bool) -> str:
    parts = []
    last = len(COLUMNS) - 1
    for index, ((_, width, right), text, code) in enumerate(zip(COLUMNS, texts, colours)):
        # The last column is not padded: trailing blanks inside a colour would survive rstrip.
        width = max(width, len(text)) if index < last else len(text)
        padded = text.rjust(width) if right else text.ljust(width)
        parts.append(_paint(padded, code, colour))
    return '  '.join(parts).rstrip()


def render(view: View, colour: bool = False, unicode: bool = True,
           width: int = WIDTH) -> str:
    """
    Return the view as text lines (no trailing newline), each at most width columns.

    colour adds ANSI colours (levels, states, header); unicode chooses the em dash and the
    degree sign over their ASCII stand-ins 'n/a' and 'C'. Long texts (the bus name, the
    messages) are cut to width.
    """
    missing = '\u2014' if unicode else 'n/a'
    degree = '\u00b0C' if unicode else 'C'
    frames = (f'in {view.frames_in if view.frames_in is not None else missing}'
              f' / out {view.frames_out if view.frames_out is not None else missing}')
    bus_level = view.bus_level or missing
    title = 'ams_can_bridge demo'
    # cut before painting: colour codes take no column but count as characters
    status = _cut(f' ({view.bus_state or "no status yet"})   frames {frames}',
                  width - len('CAN bus: ') - len(bus_level))
    lines = [
        _paint(title, BOLD, colour) + _cut(
            f'   uptime {fmt_uptime(view.uptime_s)}   bus {view.bus or missing}',
            width - len(title)),
        f'CAN bus: {_paint(bus_level, COLOURS.get(bus_level), colour)}{status}',
        '',
        _paint(_line([c[0] for c in COLUMNS], [None] * len(COLUMNS), False), BOLD, colour),
    ]
    for row in view.rows:
        texts = _cells(row, missing, degree)
        colours: list[str | None] = [None] * len(COLUMNS)
        colours[1] = STATE_COLOURS.get(row.state)
        colours[-1] = COLOURS.get(row.level)
        lines.append(_line(texts, colours, colour))
    lines.append('')
    for row in view.rows:
        if row.message:
            text = f'  {row.name}: {row.message}'
            lines.append(_paint(_cut(text, width), DIM, colour))
    command = view.last_command or 'none yet'
    answer = f' -> {view.last_answer}' if view.last_answer else ''
    lines.append(_cut(f'last command: {command}{answer}', width))
    for note in view.notes:
        lines.append(_cut(note, width))
    return '\n'.join(lines)


def _cut(text: str, width: int) -> str:
    """Cut text to width characters, marking the cut with '...'."""
    return text if len(text) <= width else text[:max(0, width - 3)] + '...'
