# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The user-facing log lines of the CAN bus's state: one line per change, never per retry.

Kept apart from the node so the wording and the once-per-change rule live in one place; it
needs no rclpy (any logger with debug/info/warning/error, such as the node's, will do).
"""
from __future__ import annotations

import time
from typing import Any

from ams_can_bridge.bus_state import BusState, UP_STATES


class BusStateLog:
    """Turn successive BusStatus snapshots into connected / lost / reconnected lines."""

    def __init__(self, logger: Any, hardware_id: str, channel: str,
                 reconnect_period: float) -> None:
        self.log = logger
        self.hardware_id = hardware_id
        self.channel = channel
        self.reconnect_period = reconnect_period
        self.state: BusState | None = None
        self.lost_at: float | None = None  # monotonic time the bus went down
        self.ever_connected = False

    def update(self, status: Any) -> None:
        """Log what changed since the last snapshot (nothing when the state is the same)."""
        if status.state == self.state:  # 5 times a second: no enum lookup for "no change"
            return
        state = BusState(status.state)
        previous, self.state = self.state, state
        reason = f': {status.reason}' if status.reason else ''
        was_up = previous in UP_STATES
        if state == BusState.CONNECTED:
            if self.lost_at is not None and self.ever_connected:
                self.log.info(f'CAN bus {self.hardware_id} reconnected after '
                              f'{time.monotonic() - self.lost_at:.1f} s')
            elif not was_up:
                self.log.info(f'CAN bus {self.hardware_id} connected')
            self.ever_connected = True
            self.lost_at = None
        elif state == BusState.ERROR_PASSIVE:
            self.log.warning(f'CAN bus {self.hardware_id} error-passive{reason}')
        elif state == BusState.REPLAY_FINISHED:
            self.log.info(f'replay of {self.channel} finished')
        elif state in (BusState.CONNECTING, BusState.STOPPED):
            self.log.debug(f'CAN bus {self.hardware_id}: {state}')
        elif was_up or self.lost_at is None:
            # the transition to "down" is logged once, not every retry of the reconnect loop
            self.lost_at = time.monotonic()
            what = 'lost' if self.ever_connected else 'cannot be opened'
            self.log.error(f'CAN bus {self.hardware_id} {what} ({state}{reason}); retrying '
                           f'every {self.reconnect_period:g} s')
        else:
            self.log.debug(f'CAN bus {self.hardware_id}: {state}{reason}')
