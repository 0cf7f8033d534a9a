# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""CanIo: python-can bus lifecycle (open, filters, receive thread, reconnect, send, record)."""
from __future__ import annotations

import errno
import logging
import math
import threading
import time
from typing import Callable

import can

from ams_can_bridge.bus_state import (
    BusState, BusStatus, DOWN_STATES, RETRY_STATES, UP_STATES)
from ams_can_bridge.can_io.config import BusConfig
from ams_can_bridge.can_io.recording import channel_name, Recording
from ams_can_bridge.errors import CanIoError, CanSendError
from ams_can_bridge.can_io.replay import ReplayBus
from ams_can_bridge.can_io.slcan import BulkReadSlcanBus, open_bulk_slcan
from ams_can_bridge.protocols.common import Frame

OnFrame = Callable[[int, bytes, bool, float], None]

_RECV_TIMEOUT = 0.1     # s: how quickly the receive thread notices stop()
_STATE_POLL = 0.5       # s: how often bus.state is asked (it may be a driver call)
_SEND_TIMEOUT = 0.05    # s: a full TX queue is a dropped frame, not a stalled caller
_CALLBACK_LOG_EVERY = 5.0  # s: throttle for errors raised by on_frame
_JOIN_TIMEOUT = 10.0    # s: how long stop() and start() wait for the receive thread to end
_UNREADABLE_LIMIT = 100  # unreadable driver messages in a row: the link itself is broken
GARBAGE_WARN_S = 10.0   # s: the bus status is WARN this long after the adapter's garbage

# SocketCAN error-frame encoding (linux/can/error.h); the virtual bus carries it unchanged.
_CAN_ERR_CRTL = 0x04
_CAN_ERR_BUSOFF = 0x40
_CAN_ERR_CRTL_PASSIVE = 0x10 | 0x20      # RX / TX passive
_CAN_ERR_CRTL_ACTIVE = 0x40
_SOCKETCAN_ERRORS = ('socketcan', 'virtual')

# Log format of bus state changes (the node filters these: it logs its own).
STATE_CHANGE_FORMAT = 'CAN bus %s: %s%s'


class _BusLost(Exception):
    """Raised inside the receive loop when the bus must be closed and re-opened."""

    def __init__(self, state: BusState, reason: str) -> None:
        super().__init__(reason)
        self.state = state
        self.reason = reason


class CanIo:
    """
    One CAN bus: a receive thread that never dies, thread-safe send, optional recording.

    ``on_frame(arbitration_id, data, is_extended_id, stamp)`` is called on the receive
    thread for every data frame whose (id, extended) is in ``filters`` (all frames when
    filters is None). Error frames are counted, remote frames ignored. ``stamp`` is the
    moment the frame was on the bus, in s since the epoch: the host clock at receive, the
    driver's timestamp with ``use_bus_time``, the log's timestamp in a replay (never the
    host clock: an entry whose timestamp is no time is skipped and counted as unreadable).
    ``last_stamp`` holds the stamp of the last frame (a replay's log time, for /clock; the
    log's first moment from the replay's start until its first frame is played).
    ``clock()`` is the devices' clock (``DeviceSet(clock=...)``): what a frame brings is
    timed by the moment it arrived, on the bus's own time (see there).
    """

    def __init__(self, config: BusConfig, on_frame: OnFrame,
                 filters: list[tuple[int, bool]] | None = None,
                 logger: logging.Logger | None = None) -> None:
        self.config = config
        self._on_frame = on_frame
        self._filters = None if filters is None else sorted(set(
            (int(i), bool(e)) for i, e in filters))
        self._std_ids = frozenset(i for i, e in self._filters or () if not e)
        self._ext_ids = frozenset(i for i, e in self._filters or () if e)
        self._log = logger or logging.getLogger('ams_can_bridge.can_io')
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._tx_lock = threading.Lock()
        self._state_cv = threading.Condition()  # wakes callers waiting for 'connected'
        self._bus: can.BusABC | ReplayBus | None = None
        self._replay: ReplayBus | None = None  # the replay being played (its skip count)
        self._recorder: Recording | None = None
        self._state = BusState.STOPPED
        self._reason = ''
        self._ever_connected = False
        self._down_since: float | None = None  # monotonic start of the current outage
        self._last_outage: float | None = None
        self.frames_in = 0
        self.frames_out = 0
        self.frames_dropped_tx = 0
        self._last_drop: tuple[float, str] | None = None  # (monotonic, why) of the last one
        self.error_frames = 0
        self.reconnects = 0
        self.callback_errors = 0
        self.frames_unreadable = 0  # messages the driver could not parse (garbled input)
        self.garbage_bytes = 0  # bytes the slcan adapter sent without a line end (dropped)
        self._garbage_at = -math.inf  # monotonic time garbage was last dropped
        self._last_unreadable_log = -_CALLBACK_LOG_EVERY
        self.last_stamp = float('nan')
        self._received: float | None = None  # monotonic arrival of the frame in on_frame
        self._last_callback_log = 0.0

    # ----------------------------------------------------------------------------- public
    def start(self) -> None:
        """Open the recording (raises OSError/ValueError if impossible) and start receiving."""
        old = self._thread
        if old is not None:
            if not self._stop.is_set():
                return  # running
            # A stop that gave up its join: the old thread ends when its driver call
            # returns (it sees the stop). Clearing the stop now would revive it next to
            # the new one: two threads reading, opening and closing one bus.
            old.join(timeout=_JOIN_TIMEOUT)
            if old.is_alive():
                raise CanIoError(f'CAN bus {self.config.hardware_id}: the previous receive '
                                 f'thread has not ended after {2 * _JOIN_TIMEOUT:g} s (a '
                                 'driver call that does not return): not started again')
            self._thread = None
        if self.config.record:
            self._recorder = Recording(self.config.record, self._log, channel_name(
                self.config.interface, self.config.channel))
        self._stop.clear()
        self._set_state(BusState.CONNECTING, '')
        self._thread = threading.Thread(target=self._run, name='can_io-rx', daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread, shut the bus down and close the recording (idempotent)."""
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=_JOIN_TIMEOUT)
            if thread.is_alive():  # kept: start() must not run a second one beside it
                self._log.warning('CAN bus %s: the receive thread did not end within %g s '
                                  '(a driver call hangs); it ends when the call returns',
                                  self.config.hardware_id, _JOIN_TIMEOUT)
            else:
                self._thread = None
        self._close_bus()
        recorder, self._recorder = self._recorder, None
        if recorder is not None:
            recorder.close()
        self._set_state(BusState.STOPPED, '', logging.DEBUG)

    def wait_connected(self, timeout: float) -> BusStatus:
        """
        Wait up to timeout s while the bus is being (re)opened; return the status then.

        Returns at once when frames flow, or when the bus will not come back by itself
        (stopped, replay finished); the caller reads ``status().connected``.
        """
        deadline = time.monotonic() + max(0.0, timeout)
        with self._state_cv:
            while self._state in RETRY_STATES:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._state_cv.wait(left)
        return self.status()

    def status(self) -> BusStatus:
        """Return a snapshot of state and counters."""
        down_since = self._down_since
        last_drop = self._last_drop
        return BusStatus(
            state=self._state, reason=self._reason, frames_in=self.frames_in,
            frames_out=self.frames_out, frames_dropped_tx=self.frames_dropped_tx,
            error_frames=self.error_frames, reconnects=self.reconnects,
            hardware_id=self.config.hardware_id, callback_errors=self.callback_errors,
            frames_unreadable=self.frames_unreadable + self._replay_skipped(),
            down_for=None if down_since is None else time.monotonic() - down_since,
            last_outage=self._last_outage,
            dropped_tx_ago=None if last_drop is None else time.monotonic() - last_drop[0],
            dropped_tx_reason='' if last_drop is None else last_drop[1],
            garbage_bytes=self.garbage_bytes,
            garbage_recent=time.monotonic() - self._garbage_at < GARBAGE_WARN_S)

    def clock(self) -> float:
        """
        Return the devices' time in s: the moment of the frame being handled, else now.

        Live: while ``on_frame`` handles a frame, the monotonic time the frame was received
        (read with its stamp), so a stall while it is handled (a busy machine, a slow disk
        under the recording) ages nothing the devices keep; otherwise the monotonic time
        now. In a replay: the log's time (``ReplayBus.log_time``), so what the devices keep
        expires on the recording's clock at any rate and however late a frame is delivered,
        as in log2bag. Monotonic time until a replay has opened its log.
        """
        replay = self._replay
        if replay is not None:
            moment = replay.log_time()
            if moment == moment:  # NaN: a log without frames
                return moment
        received = self._received
        return time.monotonic() if received is None else received

    def send(self, frame: Frame) -> None:
        """Send one frame now; raise CanSendError if not connected or the driver refuses."""
        try:
            msg = can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                              is_extended_id=frame.is_extended_id,
                              is_fd=len(frame.data) > 8, is_rx=False, check=True)
        except (ValueError, TypeError) as exc:
            with self._tx_lock:
                raise self._dropped(f'invalid frame {frame!r}: {exc}') from exc
        with self._tx_lock:
            bus = self._bus
            if bus is None or self._state not in UP_STATES:
                raise self._dropped(
                    f'CAN bus {self.config.hardware_id} is not connected ({self._state}'
                    + (f': {self._reason}' if self._reason else '') + ')')
            try:
                bus.send(msg, timeout=_SEND_TIMEOUT)
            except Exception as exc:
                raise self._dropped(f'CAN bus {self.config.hardware_id}: sending '
                                    f'0x{frame.arbitration_id:X} failed: {exc}') from exc
            self.frames_out += 1
        recorder = self._recorder
        if recorder is not None:
            msg.timestamp = time.time()
            recorder.write(msg)

    def _dropped(self, reason: str) -> CanSendError:
        """Count a frame not sent (self._tx_lock held); return the error to raise."""
        self.frames_dropped_tx += 1
        self._last_drop = (time.monotonic(), reason)
        return CanSendError(reason)

    # ---------------------------------------------------------------------------- thread
    def _set_state(self, state: BusState, reason: str, level: int = logging.INFO) -> None:
        if state != self._state or reason != self._reason:
            self._log.log(level, STATE_CHANGE_FORMAT, self.config.hardware_id, state,
                          f' ({reason})' if reason else '')
        with self._state_cv:
            if state in DOWN_STATES:
                if self._down_since is None:
                    self._down_since = time.monotonic()
            elif self._down_since is not None:
                if state in UP_STATES:
                    self._last_outage = time.monotonic() - self._down_since
                self._down_since = None
            self._state = state
            self._reason = reason
            self._state_cv.notify_all()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                bus = self._open()
            except Exception as exc:
                if self._stop.is_set():  # a stop ended the open (the slcan settling wait)
                    break
                state = BusState.RECONNECTING if self._ever_connected else BusState.ERROR
                self._set_state(state, _open_failure(self.config.interface, exc),
                                logging.WARNING)
                self._stop.wait(self.config.reconnect_period)
                continue
            try:
                self._receive(bus)
            except _BusLost as lost:
                self._set_state(lost.state, lost.reason, logging.WARNING)
            except Exception as exc:  # recv raised: adapter unplugged, driver error, ...
                self._set_state(BusState.RECONNECTING, _describe(exc), logging.WARNING)
            else:
                if isinstance(bus, ReplayBus) and bus.finished:
                    self._replay_finished(bus)
                    return
            finally:
                recorder = self._recorder
                if recorder is not None:  # no quiet ticks while the bus is away: now
                    recorder.flush()
            self._close_bus()
            self._stop.wait(self.config.reconnect_period)
        # stop() may have given up joining an open that hung
        self._set_state(BusState.STOPPED, '', logging.DEBUG)

    def _open(self) -> can.BusABC | ReplayBus:
        cfg = self.config
        if cfg.interface == 'replay':
            replay = self._replay = ReplayBus(cfg.channel, cfg.replay_rate)
            if not math.isnan(replay.log_start):  # the log's time from the start on
                self.last_stamp = replay.log_start
            bus: can.BusABC | ReplayBus = replay
        elif cfg.interface == 'slcan':  # opened exclusively; read in blocks unless told
            bus = open_bulk_slcan(cfg.channel, cfg.slcan_bulk_read, stop=self._stop,
                                  **cfg.bus_kwargs())
        else:
            # the options are whatever the interface takes (checked by BusConfig.check)
            bus = can.Bus(interface=cfg.interface, channel=cfg.channel,
                          **cfg.bus_kwargs())  # type: ignore[arg-type]
            if self._filters and type(bus)._apply_filters is not can.BusABC._apply_filters:
                # Only where the driver filters in hardware/kernel: elsewhere python-can
                # would loop over the filter list per frame, slower than our set lookup.
                try:
                    bus.set_filters([
                        {'can_id': i, 'can_mask': 0x1FFFFFFF if e else 0x7FF, 'extended': e}
                        for i, e in self._filters])
                except Exception as exc:
                    self._log.warning('CAN bus %s: driver filters not installed (%s); '
                                      'filtering in software', cfg.hardware_id, exc)
        with self._tx_lock:
            self._bus = bus
        if self._ever_connected:
            self.reconnects += 1
        self._ever_connected = True
        self._set_state(BusState.CONNECTED, f'replaying {cfg.channel}' if cfg.interface == 'replay'
                        else '')
        return bus

    def _close_bus(self) -> None:
        with self._tx_lock:
            bus, self._bus = self._bus, None
        if bus is not None:
            try:
                bus.shutdown()
            except Exception as exc:  # an unplugged adapter fails its own close
                self._log.debug('CAN bus %s shutdown: %s', self.config.hardware_id, exc)

    def _replay_finished(self, bus: ReplayBus) -> None:
        reason = f'{bus.played} frames played from {bus.path}'
        if bus.skipped:
            reason += (f'; {bus.skipped} entries skipped, their timestamp no time (last: '
                       f'{bus.last_skipped})')
        if bus.error:
            reason += f'; stopped at a bad entry: {bus.error}'
        self._set_state(BusState.REPLAY_FINISHED, reason)

    def _receive(self, bus: can.BusABC | ReplayBus) -> None:
        """Receive until stop (return), replay end (return) or failure (raise)."""
        # Locals: this loop runs ~10k times/s on a saturated bus.
        recv = bus.recv
        stop = self._stop.is_set
        on_frame = self._on_frame
        wall = time.time
        monotonic = time.monotonic
        filtering = self._filters is not None
        std_ids, ext_ids = self._std_ids, self._ext_ids
        # the bus whose driver reports its state (None: it cannot tell, or a replay)
        polled = (bus if not isinstance(bus, ReplayBus)
                  and type(bus).state is not can.BusABC.state else None)
        replay = bus if isinstance(bus, ReplayBus) else None
        slcan = bus if isinstance(bus, BulkReadSlcanBus) else None
        garbage = 0 if slcan is None else slcan.garbage_bytes  # as last counted
        decode_errors = self.config.interface in _SOCKETCAN_ERRORS
        bus_time = self.config.use_bus_time
        skipped = 0  # a replay's entries skipped for their timestamp, as last logged
        next_poll = wall() + _STATE_POLL
        unreadable_run = 0
        while not stop():
            try:
                msg = recv(_RECV_TIMEOUT)
            except (ValueError, IndexError) as exc:
                # The driver could not parse one message (slcan: a garbled serial line): a
                # bad frame, not a lost bus - unless nothing readable comes any more.
                unreadable_run += 1
                self._unreadable(exc, unreadable_run)
                continue
            unreadable_run = 0
            now, arrived = wall(), monotonic()  # together: the stamp and the devices' clock
            if msg is not None:
                if msg.is_error_frame:
                    self.error_frames += 1
                    if decode_errors:
                        self._error_frame(msg)
                elif not msg.is_remote_frame:
                    self.frames_in += 1
                    # A driver without timestamps leaves 0.0: the host clock is all we have.
                    # A replay's are the log's, each checked by ReplayBus (0.0 is a time).
                    stamp = msg.timestamp if replay is not None or (
                        bus_time and msg.timestamp > 0) else now
                    self.last_stamp = stamp
                    recorder = self._recorder
                    if recorder is not None:
                        msg.timestamp = stamp
                        recorder.write(msg)
                    if not filtering or msg.arbitration_id in (
                            ext_ids if msg.is_extended_id else std_ids):
                        self._received = arrived
                        try:
                            on_frame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id,
                                     stamp)
                        except Exception as exc:
                            self._callback_failed(msg, exc)
                        finally:
                            self._received = None
            elif replay is not None and replay.finished:
                return
            recorder = self._recorder
            if recorder is not None:  # a quiet bus: what waits in the file's buffer
                recorder.tick()
            if slcan is not None and slcan.garbage_bytes != garbage:
                self._garbage(slcan.garbage_bytes - garbage)
                garbage = slcan.garbage_bytes
            if replay is not None and replay.skipped != skipped:
                skipped = replay.skipped
                self._unreadable_log(f'log entry skipped, its timestamp is no time ({skipped} '
                                     f'so far; last: {replay.last_skipped})')
            if now >= next_poll:
                next_poll = now + _STATE_POLL
                if polled is not None:
                    self._poll_state(polled)

    def _poll_state(self, bus: can.BusABC) -> None:
        try:
            state = bus.state
        except Exception:  # drivers that cannot tell: nothing to learn
            return
        if state == can.BusState.ERROR:
            raise _BusLost(BusState.BUS_OFF, 'controller reports bus-off (BusState.ERROR)')
        if state == can.BusState.PASSIVE:
            if self._state != BusState.ERROR_PASSIVE:
                self._set_state(BusState.ERROR_PASSIVE, 'controller reports error-passive',
                                logging.WARNING)
        elif self._state == BusState.ERROR_PASSIVE:
            self._set_state(BusState.CONNECTED, '')

    def _error_frame(self, msg: can.Message) -> None:
        err = msg.arbitration_id
        if err & _CAN_ERR_BUSOFF:
            raise _BusLost(BusState.BUS_OFF, 'an error frame reports the controller bus-off')
        if err & _CAN_ERR_CRTL and len(msg.data) > 1:
            if msg.data[1] & _CAN_ERR_CRTL_PASSIVE and self._state != BusState.ERROR_PASSIVE:
                self._set_state(BusState.ERROR_PASSIVE, 'error-passive (error frame)',
                                logging.WARNING)
            elif msg.data[1] & _CAN_ERR_CRTL_ACTIVE and self._state == BusState.ERROR_PASSIVE:
                self._set_state(BusState.CONNECTED, '')

    def _unreadable(self, exc: Exception, run: int) -> None:
        self.frames_unreadable += 1
        if run >= _UNREADABLE_LIMIT:
            raise _BusLost(BusState.RECONNECTING, f'{run} unreadable messages in a row from the '
                           f'driver, last: {_describe(exc)}')
        self._unreadable_log(f'unreadable message from the driver dropped '
                             f'({self.frames_unreadable} so far): {_describe(exc)}')

    def _garbage(self, size: int) -> None:
        """Count bytes the adapter sent without a line end (dropped by the slcan bus)."""
        self.garbage_bytes += size
        self._garbage_at = time.monotonic()
        self._unreadable_log(f'{size} bytes without a line end from the adapter dropped '
                             f'({self.garbage_bytes} so far): not slcan, check its serial '
                             'settings (baud rate) and firmware')

    def _unreadable_log(self, what: str) -> None:
        """Log what could not be read, at most every _CALLBACK_LOG_EVERY."""
        now = time.monotonic()
        if now - self._last_unreadable_log >= _CALLBACK_LOG_EVERY:
            self._last_unreadable_log = now
            self._log.warning('CAN bus %s: %s', self.config.hardware_id, what)

    def _replay_skipped(self) -> int:
        replay = self._replay
        return 0 if replay is None else replay.skipped

    def _callback_failed(self, msg: can.Message, exc: Exception) -> None:
        self.callback_errors += 1
        now = time.monotonic()
        if now - self._last_callback_log >= _CALLBACK_LOG_EVERY:
            self._last_callback_log = now
            self._log.error('frame 0x%X [%s] handler failed (%d so far): %s: %s',
                            msg.arbitration_id, msg.data.hex(' ').upper(),
                            self.callback_errors, type(exc).__name__, exc)


def _open_failure(interface: str, exc: BaseException) -> str:
    """Return why the bus did not open; a kernel without SocketCAN is named as such."""
    if interface == 'socketcan' and getattr(exc, 'errno', None) == errno.EAFNOSUPPORT:
        # python-can's socket(PF_CAN) itself fails: no CAN on this machine, not a bad adapter
        return (f'this machine has no SocketCAN ({_describe(exc)}: the kernel has no CAN '
                'support, as in WSL, many containers and macOS): load it (sudo modprobe can '
                'can_raw) or use another can.interface: slcan for a USB-serial adapter '
                '(can.channel /dev/ttyACM0), pcan, kvaser, ..., or virtual to try the bridge '
                'without hardware')
    return _describe(exc)


def _describe(exc: BaseException) -> str:
    """python-can's reason, with the exception type when the text alone is unclear."""
    text = str(exc).strip()
    cause = exc.__cause__ or exc.__context__
    if cause is not None and str(cause) and str(cause) not in text:
        text = f'{text}: {cause}' if text else str(cause)
    return text or type(exc).__name__
