# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The state of the CAN bus and a snapshot of its counters: the bottom layer, beside errors.py.

The bus layer (``can_io/``) sets them; the engine, the reports and the ROS and bag sinks read
them without importing python-can. No rclpy and no python-can here.
"""
from __future__ import annotations

from dataclasses import dataclass
import enum


class BusState(enum.StrEnum):
    """
    The state of the bridge's CAN bus (the receive thread's view of it).

    str-valued: logs, diagnostics and ``str(state)`` show the value ('bus-off'), and a
    state compares equal to its text.
    """

    CONNECTING = 'connecting'            # first attempt to open the bus under way
    CONNECTED = 'connected'
    RECONNECTING = 'reconnecting'        # was up, lost, reopening
    ERROR = 'error'                      # never came up, retrying
    BUS_OFF = 'bus-off'
    ERROR_PASSIVE = 'error-passive'      # still receives
    REPLAY_FINISHED = 'replay finished'  # a replay reached the end of its file
    STOPPED = 'stopped'


# States in which the receive thread is still (re)opening the bus: it may come back alone.
RETRY_STATES = frozenset({BusState.CONNECTING, BusState.RECONNECTING, BusState.ERROR,
                          BusState.BUS_OFF})
# States in which the bus is down and being reopened (an outage is being timed).
DOWN_STATES = frozenset({BusState.RECONNECTING, BusState.ERROR, BusState.BUS_OFF})
# States in which frames flow.
UP_STATES = frozenset({BusState.CONNECTED, BusState.ERROR_PASSIVE})


@dataclass(frozen=True)
class BusStatus:
    """A snapshot of the bus state and counters (cheap to take, safe to keep)."""

    state: BusState
    reason: str
    frames_in: int
    frames_out: int
    frames_dropped_tx: int
    error_frames: int
    reconnects: int
    hardware_id: str
    callback_errors: int = 0
    frames_unreadable: int = 0         # messages the driver could not parse
    down_for: float | None = None      # s the bus has been down (None while it is up)
    last_outage: float | None = None   # s the last outage lasted, once the bus is back
    dropped_tx_ago: float | None = None  # s since a frame to send was last dropped (None: never)
    dropped_tx_reason: str = ''        # why that frame was dropped
    garbage_bytes: int = 0             # bytes the adapter sent without a line end, dropped
    garbage_recent: bool = False       # some of them within the last GARBAGE_WARN_S

    @property
    def connected(self) -> bool:
        """Tell whether frames flow (connected, or error-passive which still receives)."""
        return self.state in UP_STATES
