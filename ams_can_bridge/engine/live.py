# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The engine as the live bridge runs it, without ROS: its view of the bus, its periodic thread.

The node opens the bus (``CanIo``) in configure and closes it in cleanup; the engine's
callbacks ask through ``BusView`` whether or not it is open. A closed bus reports
``stopped``; a message no frame stamps is stamped with the replayed log's time in a replay
(so a replay's stale messages and diagnostics follow the recording), with the wall clock
otherwise. The periodic work runs on one thread of its own (``TimerThread``: see timer.py
for why not executor timers), so an idle bridge wakes no executor at all; ``log2bag`` runs
the same engine on the log's time instead (``engine.core.Schedule``).
"""
from __future__ import annotations

import gc
import logging
import math
import time
from typing import Callable, Protocol

from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.can_io.core import STATE_CHANGE_FORMAT
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.core import Engine, Sink
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.engine.startup import BusSettings
from ams_can_bridge.engine.timer import TimerThread

CLOCK_PERIOD = 0.01  # s between /clock messages of a replay (can.replay_clock)


def settle_heap() -> None:
    """
    Collect what a configure left behind, then keep the rest out of later full collections.

    A full collection walks every object the collector tracks, with the interpreter held:
    every thread stops, the heartbeat's too. The devices, codecs and DBCs built at configure
    live until cleanup, so they are frozen (``gc.freeze``) and later full collections walk
    only what came after. Unfrozen first: the objects of an earlier configure, released by
    its cleanup, are collected now rather than kept forever.
    """
    gc.unfreeze()
    gc.collect()
    gc.freeze()


class OpenBus(Protocol):
    """What the view reads of an open bus (``CanIo``)."""

    last_stamp: float  # the stamp of the last frame received (NaN: none yet)

    def status(self) -> BusStatus:
        """Return a snapshot of the bus state and counters."""

    def clock(self) -> float:
        """Return the devices' clock: the handled frame's arrival, a replay's log time."""


def device_clock(bus: Callable[[], OpenBus | None]) -> Callable[[], float]:
    """
    Return the devices' clock (``DeviceSet(clock=...)``): the bus's (``CanIo.clock``).

    Live, the monotonic moment each frame arrived while it is handled, else now; in a
    replay, the log's time. ``bus`` returns the open bus (None while it is closed): until
    one opens, monotonic time (nothing has been heard to time); after it closed, the last
    one's clock, so that a replay's devices do not jump back from the log's time.
    """
    last: list[OpenBus] = []

    def clock() -> float:
        current = bus()
        if current is not None:
            if not last or last[0] is not current:
                last[:] = [current]
            return current.clock()
        return last[0].clock() if last else time.monotonic()
    return clock


class BusView:
    """The bus status, the stamp clock, the command keys and /clock, for the engine."""

    def __init__(self, hardware_id: str, replaying: bool, gate: CommandGate,
                 bus: Callable[[], OpenBus | None],
                 wall: Callable[[], float] = time.time) -> None:
        """``bus`` returns the open bus, or None while it is closed."""
        self.replaying = replaying
        self.gate = gate
        self.bus = bus
        self.wall = wall
        self.closed = BusStatus(
            state=BusState.STOPPED, reason='', frames_in=0, frames_out=0, frames_dropped_tx=0,
            error_frames=0, reconnects=0, hardware_id=hardware_id)

    def now(self) -> float:
        """Return the time to stamp with when no frame gives one: a replay's log time."""
        bus = self.bus()
        if self.replaying and bus is not None:
            stamp = bus.last_stamp
            if math.isfinite(stamp):
                return stamp
        return self.wall()

    def status(self) -> BusStatus:
        """Return the bus state and counters; a closed bus is ``stopped``."""
        bus = self.bus()
        return self.closed if bus is None else bus.status()

    def values(self) -> dict[str, str]:
        """Return the command keys of the CAN bus report."""
        return {'commands_allowed': str(self.gate.allowed).lower(),
                'commands_enabled': str(self.gate.enabled).lower(),
                'commands_enabled changes': str(self.gate.changes)}

    def clock_stamp(self) -> float:
        """Return the replayed log time for /clock (NaN: no frame yet, or the bus closed)."""
        bus = self.bus()
        return bus.last_stamp if bus is not None else math.nan


def live_engine(device_set: DeviceSet, sink: Sink, settings: BusSettings, gate: CommandGate,
                bus: Callable[[], OpenBus | None], *, status_prefix: str,
                diagnostics_period: float, on_bus_status: Callable[[BusStatus], None],
                logger: Callable[[str], logging.Logger], thread_name: str,
                on_replay_end: Callable[[], None] | None = None,
                ) -> tuple[Engine, BusView, TimerThread]:
    """
    Return the engine of a live bridge, its view of the bus, its periodic thread (stopped).

    ``bus`` returns the open bus (None while closed); ``logger(part)`` returns the stdlib
    logger a part logs to (the node's, in the node). ``on_replay_end`` (``can.replay_exit``)
    is called once, on the periodic thread, when the replay has finished and the last
    diagnostics (``replay finished``) have been published.
    """
    if on_replay_end is not None:
        on_bus_status = _after_replay(on_bus_status, lambda: engine.publish_diagnostics(),
                                      on_replay_end)
    view = BusView(settings.hardware_id, settings.replaying, gate, bus)
    engine_logger = logger('engine')
    engine_logger.setLevel(logging.DEBUG)  # the node's logger decides what is shown
    engine = Engine(device_set, sink, status_prefix=status_prefix,
                    interface=settings.interface, bus_status=view.status, now=view.now,
                    bus_values=view.values, on_bus_status=on_bus_status, logger=engine_logger)
    periodic = TimerThread(thread_name, logger('periodic'))
    for period, call in engine.schedule(diagnostics_period):
        periodic.every(period, call)
    if settings.replay_clock:
        periodic.every(CLOCK_PERIOD, lambda: engine.publish_clock(view.clock_stamp()))
    return engine, view, periodic


def _after_replay(on_bus_status: Callable[[BusStatus], None], publish: Callable[[], None],
                  on_end: Callable[[], None]) -> Callable[[BusStatus], None]:
    """Return ``on_bus_status`` that also publishes and calls ``on_end`` once at the end."""
    ended: list[bool] = []

    def watch(status: BusStatus) -> None:
        on_bus_status(status)
        if status.state == BusState.REPLAY_FINISHED and not ended:
            ended.append(True)
            publish()  # every battery_state went out with its frame: the last status now
            on_end()
    return watch


def open_bus(config: BusConfig, engine: Engine, device_set: DeviceSet, gate: CommandGate,
             logger: logging.Logger) -> CanIo:
    """Return the bus (not started): its frames go to the engine, the gate sends on it."""
    # CanIo logs every state change; the node logs the user-facing transitions itself
    # (ros/bus_log.py: once per change, with what happens next), so only CanIo's other
    # problems pass.
    logger.setLevel(logging.WARNING)
    logger.addFilter(lambda record: record.msg != STATE_CHANGE_FORMAT)
    can_io = CanIo(config, engine.on_frame, device_set.filters, logger)
    gate.attach_bus(can_io)
    return can_io
