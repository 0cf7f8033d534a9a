# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Terminal view of the demo and of ``monitor``: plain data in, text out (no ROS, no curses).

Both fill a ``View`` from a bridge's real ROS topics (``device_row`` merges one device's
BatteryState and DiagnosticStatus into its row); ``render`` turns it into aligned text with
units, NaN shown as a dash (or 'n/a' without Unicode), and the diagnostics level in colour
when the output is a terminal; ``show`` draws it on a ``Screen`` until stopped. Keeping this
free of ROS lets it be tested with known data: one table for the demo and the monitor.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import re
import threading
import time
from typing import Any, Callable, TextIO

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
# Keys of diagnostics values that hold a device's state or status name, best first.
STATE_KEYS = ('state', 'ams state', 'evms state', 'status')


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
    """Everything on one screen of the demo or the monitor."""

    title: str = 'ams_can_bridge demo'
    bus: str = ''
    uptime_s: float = 0.0
    frames_in: int | None = None
    frames_out: int | None = None
    bus_state: str = ''
    bus_level: str = ''
    rows: list[DeviceRow] = field(default_factory=list)
    last_command: str | None = ''  # None: no command line (the monitor sends none)
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
# names are their types, and a team's own names say more than the type.
COLUMNS = (
    ('DEVICE', 6, False), ('STATE', 11, False),
    ('VOLTAGE', 7, True), ('CURRENT', 8, True), ('SOC', 7, True),
    ('CELLS', 14, True), ('TEMP', 8, True), ('DIAG', 5, False),
)
WIDTH = 80  # columns of a default terminal: every line of the view fits
# A longer state ('CHARGE_ERROR', the head of a message: '96 of 96 cell v.') widens the STATE
# column of every row as a long name widens DEVICE: it spilled into VOLTAGE, the row alone.
STATE_WIDTH_MAX = 16
# A longer instance name widens the DEVICE column (the row then passes 80 columns) up to
# this, and is cut beyond it: a column per row would break the alignment.
DEVICE_WIDTH_MAX = 16


def fmt_cells(low: float, high: float, missing: str) -> str:
    """Format the cell voltage range as '3.900..3.920 V', or the missing marker."""
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (low, high)):
        return missing
    return f'{low:.3f}..{high:.3f} V'


def _cells(row: DeviceRow, missing: str, degree: str, widths: list[int]) -> list[str]:
    pct = row.percentage * 100.0 if isinstance(row.percentage, (int, float)) else NAN
    return [
        _cut(row.name, widths[0]), _cut(row.state, widths[1]) or missing,
        fmt_value(row.voltage, 'V', 1, missing),
        fmt_value(row.current, 'A', 1, missing),
        fmt_value(pct, '%', 1, missing),
        fmt_cells(row.cell_min, row.cell_max, missing),
        fmt_value(row.temperature, degree, 1, missing),
        row.level or missing,
    ]


def _line(texts: list[str], colours: list[str | None], colour: bool, widths: list[int]) -> str:
    parts = []
    last = len(COLUMNS) - 1
    for index, ((_, _, right), text, code) in enumerate(zip(COLUMNS, texts, colours)):
        width = widths[index]
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
    messages) are cut to width; only a device name longer than 6 characters widens the
    table beyond 80 columns.
    """
    missing = '\u2014' if unicode else 'n/a'
    degree = '\u00b0C' if unicode else 'C'
    frames = (f'in {view.frames_in if view.frames_in is not None else missing}'
              f' / out {view.frames_out if view.frames_out is not None else missing}')
    bus_level = _cut(view.bus_level, len('LEVEL 255')) or missing
    title = _cut(view.title, width)
    widths = [column[1] for column in COLUMNS]
    widths[0] = min(DEVICE_WIDTH_MAX, max([widths[0]] + [len(r.name) for r in view.rows]))
    widths[1] = min(STATE_WIDTH_MAX,
                    max([widths[1]] + [len(printable(r.state)) for r in view.rows]))
    # cut before painting: colour codes take no column but count as characters
    status = _cut(f' ({view.bus_state or "no status yet"})   frames {frames}',
                  width - len('CAN bus: ') - len(bus_level))
    lines = [
        _paint(title, BOLD, colour) + _cut(
            f'   uptime {fmt_uptime(view.uptime_s)}   bus {view.bus or missing}',
            width - len(title)),
        f'CAN bus: {_paint(bus_level, COLOURS.get(bus_level), colour)}{status}',
        '',
        _paint(_line([c[0] for c in COLUMNS], [None] * len(COLUMNS), False, widths),
               BOLD, colour),
    ]
    for row in view.rows:
        texts = _cells(row, missing, degree, widths)
        colours: list[str | None] = [None] * len(COLUMNS)
        colours[1] = STATE_COLOURS.get(row.state)
        colours[-1] = COLOURS.get(row.level)
        lines.append(_line(texts, colours, colour, widths))
    lines.append('')
    for row in view.rows:
        if row.message:
            text = f'  {row.name}: {row.message}'
            lines.append(_paint(_cut(text, width), DIM, colour))
    if view.last_command is not None:
        command = view.last_command or 'none yet'
        answer = f' -> {view.last_answer}' if view.last_answer else ''
        lines.append(_cut(f'last command: {command}{answer}', width))
    for note in view.notes:
        lines.append(_cut(note, width))
    return '\n'.join(lines)


# Control and format characters (ESC, CR, BEL, bidi overrides): a /diagnostics message
# carrying '\x1b[2J' cleared the terminal of whoever watched. Every text from a message is
# shown with them escaped, as Python writes them.
_CONTROL = re.compile(r'[\x00-\x1f\x7f-\x9f\u200b-\u200f\u202a-\u202e\u2066-\u2069]')


def printable(text: str) -> str:
    """Return text with its control characters escaped (ESC as backslash x1b), the rest kept."""
    return _CONTROL.sub(lambda m: m.group().encode('unicode_escape').decode('ascii'), text)


def _cut(text: str, width: int) -> str:
    """Cut text (control characters escaped first) to width characters, marking the cut."""
    text = printable(text)
    return text if len(text) <= width else text[:max(0, width - 3)] + '...'


# --- one device's row, from its last BatteryState and DiagnosticStatus ---------------------

# A reading in a diagnostics message ('-27.71 A', '222.9 V', 'SoC 80 %'). The table shows
# the same quantity from battery_state, which comes with every frame, while the diagnostics
# come every diagnostics_period (1 s by default): both on one screen would show two
# currents for one device at one moment. The summary line keeps the rest of the message.
_READING = re.compile(r'(SoC )?([-+]?(nan|inf|\d+(\.\d*)?(e[-+]?\d+)?) (V|A|%)|not available)',
                      re.IGNORECASE)


def without_readings(message: str) -> str:
    """Return a diagnostics message without its parts that are only V / A / % readings."""
    kept = [part.strip() for part in message.split(';')
            if not all(_READING.fullmatch(item.strip()) for item in part.split(','))]
    return '; '.join(part for part in kept if part)


def device_row(name: str, msg: Any, status: Any) -> DeviceRow:
    """
    Build one device's row from its last BatteryState and DiagnosticStatus (either None).

    The numbers come from the BatteryState only; the message keeps what the table does not
    show (``without_readings``, and nothing when it only repeats the state).
    """
    row = DeviceRow(name=name, type=name)
    if status is not None:
        values = {kv.key: kv.value for kv in status.values}
        row.level = level_name(status.level)
        row.state = state_of(values, status.message, row.level)
        message = without_readings(status.message)
        message = message if message != row.state else ''  # 'bms16: OK' says nothing new
        row.message = '; '.join(part for part in (pack_figures(values), message) if part)
    if msg is not None:
        row.voltage = msg.voltage
        row.current = msg.current
        row.percentage = msg.percentage
        row.temperature = msg.temperature
        row.cell_min, row.cell_max = cell_range(list(msg.cell_voltage))
    return row


def pack_figures(values: dict[str, str]) -> str:
    """
    Return a pack's current limits and time-to-go from its diagnostics values ('' otherwise).

    The table has no column for them; a supervisor watching a pack wants them beside its
    events (which the pack's message carries).
    """
    if 'charge_current_limit' not in values:
        return ''
    keys = ('charge_current_limit', 'discharge_current_limit')
    amps = {key: _number(values.get(key)) for key in keys}
    return (f"limits: charge {fmt_value(amps['charge_current_limit'], 'A', 0, 'n/a')}, "
            f"discharge {fmt_value(amps['discharge_current_limit'], 'A', 0, 'n/a')}; "
            f"to empty {fmt_duration(_number(values.get('time_to_empty')))}, "
            f"to full {fmt_duration(_number(values.get('time_to_full')))}")


def _number(text: str | None) -> float:
    try:
        return float(text) if text is not None else NAN
    except ValueError:
        return NAN


def fmt_duration(seconds: float) -> str:
    """Return a time-to-go as '2 h 05 min' or '7 min' ('n/a' while unknown)."""
    if not math.isfinite(seconds) or seconds < 0:
        return 'n/a'
    minutes = int(round(seconds / 60.0))
    return f'{minutes // 60} h {minutes % 60:02d} min' if minutes >= 60 else f'{minutes} min'


def state_of(values: dict[str, str], message: str, level: str = '') -> str:
    """
    Return the state or status name a device reports, from its diagnostics.

    AMS and EVMS3 report a 'state' value; the others lead their message with their status
    ('OK', 'error LOW_CELL', 'alarms ...'); the IVT-S has no state: it is measuring.
    """
    for key, value in values.items():
        if key.lower() in STATE_KEYS and value:
            return value
    if level == 'STALE':
        return 'silent'
    head = message.split(';')[0].strip()
    if _READING.match(head):  # the IVT-S leads with its current ('-27.71 A, 222.9 V')
        return 'measuring'
    return head if len(head) <= STATE_WIDTH_MAX else head[:STATE_WIDTH_MAX - 1] + '.'


def to_int(text: str | None) -> int | None:
    """Return the int a diagnostics value holds, None when it holds none."""
    try:
        return int(text) if text is not None else None
    except ValueError:
        return None


# --- the screen ------------------------------------------------------------------------------

class Screen:
    """Where the view is drawn: redrawn in place on a terminal, else text snapshots."""

    def __init__(self, out: TextIO, plain: bool = False) -> None:
        self.out = out
        self.tty = out.isatty() and not plain
        self.unicode = self.tty and 'utf' in (getattr(out, 'encoding', '') or '').lower()

    def interval(self, requested: float | None) -> float:
        """Return the seconds between draws: 4 redraws a second on a terminal, else 1 s."""
        return requested or (0.25 if self.tty else 1.0)

    def draw(self, view: View, uptime: float) -> None:
        """Draw one view (a snapshot headed by its time when not on a terminal)."""
        text = render(view, colour=self.tty, unicode=self.unicode)
        if self.tty:
            self.out.write('\033[H' + text.replace('\n', '\033[K\n') + '\033[K\033[J')
        else:
            self.out.write(f'--- t = {uptime:.1f} s ---\n{text}\n\n')
        self.out.flush()


def show(screen: Screen, make_view: Callable[[float], View], stop: threading.Event,
         duration: float = 0.0, interval: float | None = None) -> None:
    """Draw make_view(uptime) every interval until stop is set or duration (0: none) passed."""
    period = screen.interval(interval)
    started = time.monotonic()
    if screen.tty:
        screen.out.write('\033[?25l\033[2J')  # hide the cursor, clear once
    try:
        while True:
            uptime = time.monotonic() - started
            screen.draw(make_view(uptime), uptime)
            remaining = duration - uptime if duration else math.inf
            if remaining <= 0 or stop.wait(min(period, max(remaining, 0.01))):
                break
    finally:
        if screen.tty:
            screen.out.write('\033[?25h\n')
            screen.out.flush()
