# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Where probe's frames come from: a log, or a live bus it can only receive from.

A log is read with log2bag's reader (``offline/log_frames.py``: every format log2bag reads,
bad entries counted). A live bus is opened receive-only: probe holds it through
``ReceiveOnly``, which has no way to send, and an slcan adapter is opened in its listen-only
mode (``L`` instead of ``O``: the controller does not even acknowledge frames). Only such an
interface may try bit rates (``--bitrate auto``): at a wrong rate a controller that takes
part in the bus would fill it with error frames.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import inspect
import math
import time
from typing import Any, TextIO

import can
from can.interfaces.slcan import slcanBus

from ams_can_bridge.can_io.slcan import open_bulk_slcan
from ams_can_bridge.errors import ConfigError, LogFileError
from ams_can_bridge.offline.log2bag import check_frames, Summary
from ams_can_bridge.offline.log_frames import LogFrames
from ams_can_bridge.probe.traffic import Traffic

# The common rates of battery buses, most common first: --bitrate auto tries, in this order,
# those the interface can be set to (AUTO_RATES).
STANDARD_RATES = (500_000, 250_000, 1_000_000, 125_000, 800_000, 100_000, 50_000, 20_000,
                  10_000)
# python-can's slcan sets a rate only from its own S0..S9 table: 800 kbit/s is not in it (its
# S7 is 750 kbit/s), and asking for it ends in "Invalid bitrate". Only these are tried.
SLCAN_RATES: frozenset[int] = frozenset(getattr(slcanBus, '_BITRATES', {}))
AUTO_RATES = tuple(r for r in STANDARD_RATES if r in SLCAN_RATES) if SLCAN_RATES \
    else tuple(r for r in STANDARD_RATES if r != 800_000)
AUTO_WINDOW_S = 1.0  # s listened at each rate
AUTO_FRAMES = 2      # data frames that show the rate is right
POLL_S = 0.2         # s a receive waits before the progress line is redrawn
SLCAN_TIMEOUT_S = 0.1  # the serial port's read timeout (a stop is seen this quickly)


def slcan_listens_silently() -> bool:
    """Tell whether this python-can opens slcan listen-only (``listen_only``, the L command)."""
    return 'listen_only' in inspect.signature(slcanBus.__init__).parameters


@dataclass
class LiveInfo:
    """How a live bus was listened to: for the report and the params file."""

    interface: str
    channel: str
    bitrate: int  # 0: left as the adapter is
    listen_only: bool
    tried: list[tuple[int, int]] = field(default_factory=list)  # --bitrate auto: (rate, frames)
    # --bitrate auto: False when frames came at two different rates (a pty or a software link
    # has no bit rate of its own: any rate "works"), so the rate found proves nothing
    rate_determined: bool = True
    refused: list[int] = field(default_factory=list)  # rates the adapter would not take

    def describe(self) -> str:
        """Say where and how probe listened."""
        rate = f' at {self.bitrate} bit/s' if self.bitrate else ''
        found = ('rate found by trying the standard ones' if self.rate_determined else
                 'rate not determined: frames came at every rate tried')
        how = [what for what, yes in (('listen-only', self.listen_only), (found, self.tried))
               if yes]
        return f'{self.interface}:{self.channel}{rate}' + (f' ({", ".join(how)})' if how else '')


class ReceiveOnly:
    """A python-can bus probe can only receive from: it has no send."""

    def __init__(self, bus: can.BusABC) -> None:
        """Hold the bus; nothing else gets to it."""
        self._bus = bus

    def recv(self, timeout: float) -> can.Message | None:
        """Return the next message, None after timeout."""
        return self._bus.recv(timeout)

    def close(self) -> None:
        """Close the bus (an adapter that is gone is closed already)."""
        try:
            self._bus.shutdown()
        except Exception:  # unplugged under us: nothing left to close
            pass


def read_log(path: str) -> Traffic:
    """Read every frame of a log; LogFileError (one line) when it holds none usable."""
    frames = LogFrames(path)
    traffic = Traffic()
    add = traffic.add
    read = 0
    try:
        # log2bag's frames: its own readers for .log and .blf (faster, and a BLF object of 0
        # bytes ends the reading there, where python-can's parser loops on it for ever)
        for stamp, can_id, data, extended, error, remote in frames.frames():
            read += 1
            if error:
                traffic.error_frames += 1
            elif remote:
                traffic.remote_frames += 1
            else:
                add(can_id, extended, data, stamp)
    finally:
        frames.close()
    check_frames(path, frames, Summary(frames_read=read, first_stamp=traffic.first), None,
                 traffic.first, traffic.last)
    return traffic


def open_bus(interface: str, channel: str, bitrate: int, options: dict[str, Any],
             listen_only: bool) -> ReceiveOnly:
    """Open a bus receive-only; ConfigError (one line) when it does not open."""
    kwargs = dict(options)
    if bitrate:
        kwargs['bitrate'] = bitrate
    bus: can.BusABC
    try:
        if interface == 'slcan':
            kwargs.setdefault('timeout', SLCAN_TIMEOUT_S)
            if listen_only:
                kwargs['listen_only'] = True
            bus = open_bulk_slcan(channel, **kwargs)
        else:
            bus = can.Bus(interface=interface, channel=channel, **kwargs)
    except Exception as exc:  # python-can's, the OS's: the reason is in the text
        text = str(exc).strip() or type(exc).__name__
        raise ConfigError(f'cannot open {interface}:{channel}'
                          + (f' at {bitrate} bit/s' if bitrate else '') + f': {text}') from None
    return ReceiveOnly(bus)


class Listener:
    """Listen to a live bus for a while and count what comes, with a progress line."""

    def __init__(self, stream: TextIO) -> None:
        """Draw progress on stream (only when it is a terminal)."""
        self.stream = stream
        self.draw = stream.isatty()
        self.traffic = Traffic()

    def say(self, text: str) -> None:
        """Write one line (ending a progress line first)."""
        self.stream.write(('\r\x1b[K' if self.draw else '') + f'probe: {text}\n')
        self.stream.flush()

    def listen(self, bus: ReceiveOnly, seconds: float, what: str,
               report_on_ctrl_c: bool = True) -> int:
        """
        Take frames for ``seconds``; return how many data frames came.

        Ctrl-C ends the listening early and what came is reported; with
        ``report_on_ctrl_c`` false (trying rates) it ends probe.
        """
        traffic = self.traffic
        before = traffic.frames
        started = time.monotonic()
        end = started + seconds
        try:
            while (left := end - time.monotonic()) > 0:
                msg = bus.recv(min(left, POLL_S))
                if msg is not None:
                    if msg.is_error_frame:
                        traffic.error_frames += 1
                    elif msg.is_remote_frame:
                        traffic.remote_frames += 1
                    else:
                        stamp = msg.timestamp if math.isfinite(msg.timestamp) and \
                            msg.timestamp > 0 else time.time()
                        traffic.add(msg.arbitration_id, msg.is_extended_id, msg.data, stamp)
                self._progress(what, time.monotonic() - started, seconds)
        except KeyboardInterrupt:
            if not report_on_ctrl_c:
                raise
            self.say('stopped (Ctrl-C): reporting what came so far')
        if self.draw:
            self.stream.write('\r\x1b[K')
        return traffic.frames - before

    def _progress(self, what: str, done: float, total: float) -> None:
        if self.draw:
            self.stream.write(f'\rprobe: {what}: {done:4.1f} of {total:g} s, '
                              f'{self.traffic.frames:,} frames, {len(self.traffic.ids)} IDs ')
            self.stream.flush()


def listen_live(interface: str, channel: str, bitrate: int | str, seconds: float,
                options: dict[str, Any], stream: TextIO) -> tuple[Traffic, LiveInfo]:
    """Listen to a live bus; ``bitrate`` 'auto' tries AUTO_RATES listen-only first."""
    silent = interface == 'slcan' and slcan_listens_silently()
    listener = Listener(stream)
    if bitrate == 'auto':
        if not silent:
            raise ConfigError(
                f'--bitrate auto tries rates only on an adapter that listens without taking '
                f'part in the bus (slcan, in its listen-only mode); on {interface} give the '
                'rate of your bus: --bitrate 500000 (or 250000, 1000000, 125000)')
        info = LiveInfo(interface, channel, 0, True)
        bus = _find_rate(listener, info, options)
    else:
        info = LiveInfo(interface, channel, int(bitrate), silent)
        bus = open_bus(interface, channel, info.bitrate, options, silent)
    try:
        mode = (' (listen-only)' if info.listen_only else
                " (this python-can opens slcan without listen-only: the adapter acknowledges "
                'frames)' if interface == 'slcan' else '')
        rate = f' at {info.bitrate} bit/s' if info.bitrate else ''
        listener.say(f'listening on {interface}:{channel}{rate}{mode} for {seconds:g} s; '
                     'nothing is sent')
        listener.listen(bus, seconds, 'listening')
    finally:
        bus.close()
    if not listener.traffic.frames:
        raise LogFileError(f'no frame in {seconds:g} s on {interface}:{channel}{rate}: is the '
                           'bus running at that rate (or try --bitrate auto on slcan), the '
                           'adapter wired to CAN-H and CAN-L, the bus terminated?')
    return listener.traffic, info


def _find_rate(listener: Listener, info: LiveInfo, options: dict[str, Any]) -> ReceiveOnly:
    """
    Open listen-only at each rate the interface has until frames come; return that bus, open.

    A rate the adapter refuses is skipped, not the end of the search. Frames at one rate are
    checked at one other rate: a real controller at a wrong rate sees only errors, so frames
    there too mean the link has no bit rate of its own (a pty, a software link) and the rate
    is reported as not determined rather than as the first one tried.
    """
    listener.say(f'--bitrate auto: trying {len(AUTO_RATES)} standard rates, listen-only '
                 f'({AUTO_WINDOW_S:g} s each); nothing is sent')
    errors: list[str] = []
    for index, rate in enumerate(AUTO_RATES):
        heard = _try_rate(listener, info, rate, options, errors)
        if heard < AUTO_FRAMES:
            continue
        listener.say(f'{rate} bit/s: {heard} frames in {AUTO_WINDOW_S:g} s')
        other = AUTO_RATES[index + 1] if index + 1 < len(AUTO_RATES) else AUTO_RATES[0]
        if _try_rate(listener, info, other, options, errors) >= AUTO_FRAMES:
            info.rate_determined = False
            listener.say(f'{other} bit/s: frames too: the link has no bit rate of its own '
                         '(a pty or a software link?); rate not determined')
        listener.traffic = Traffic()
        info.bitrate = rate
        return open_bus(info.interface, info.channel, rate, options, True)
    if len(errors) == len(AUTO_RATES):
        raise ConfigError(f'--bitrate auto: {info.interface}:{info.channel} opened at no rate '
                          f'({"; ".join(errors[:2])})')
    refused = (f'; refused by the adapter: {", ".join(str(r) for r in info.refused)}'
               if info.refused else '')
    raise LogFileError(f'no traffic at any rate on {info.interface}:{info.channel} ('
                       + ', '.join(str(r) for r in AUTO_RATES) + ' bit/s, '
                       f'{AUTO_WINDOW_S:g} s each{refused}): is the bus running, the adapter '
                       'wired to CAN-H and CAN-L, the bus terminated?')


def _try_rate(listener: Listener, info: LiveInfo, rate: int, options: dict[str, Any],
              errors: list[str]) -> int:
    """Listen at one rate for AUTO_WINDOW_S; return the data frames heard (0 if refused)."""
    try:
        bus = open_bus(info.interface, info.channel, rate, options, True)
    except ConfigError as exc:
        info.refused.append(rate)
        errors.append(str(exc))
        listener.say(f'{rate} bit/s: not taken by the adapter, skipped ({exc})')
        return 0
    try:
        heard = listener.listen(bus, AUTO_WINDOW_S, f'{rate} bit/s', report_on_ctrl_c=False)
    finally:
        bus.close()
    info.tried.append((rate, heard))
    listener.traffic = Traffic()  # a frame or two at a wrong rate is no traffic
    return heard
