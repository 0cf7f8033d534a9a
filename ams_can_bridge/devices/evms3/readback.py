# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
EVMS3 configuration read-back: ask with ID 51, collect the answer on 52..56. No rclpy.

ZEVA's open EVMS3 firmware (MIT, August 2021) answers a frame with ID 51 (any data, DLC 0
is enough) with its whole configuration: IDs 52..55 in the layout of 32..35 and 56 in the
layout of 36. The reader collects one answer for a waiting ``read`` (the service), and keeps
the last packets whoever asked (a ZEVA Monitor, for example) for the diagnostics: a set
counts as one answer when its five packets came within ANSWER_WINDOW of each other, so a
lone 52/53 (a ZEVA motor controller's settings frames share those IDs) is never shown as
the EVMS's configuration.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

from ams_can_bridge.devices.ports import CallPort, CANCEL_POLL, cancel_reason, SendFrame
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import (
    CONFIG_FIELDS, ConfigReadback, ConfigReport, READBACK_IDS, READBACK_NAMES)
from ams_can_bridge.protocols.evms3_config import sentinel_text

ANSWER_WINDOW = 1.0  # s: the EVMS sends the five packets of one answer back to back
_UNITS = {f.name: f.unit for f in CONFIG_FIELDS}


@dataclass(frozen=True)
class ReadResult:
    """What one read_config got: a complete read-back, or why not (nothing to set then)."""

    readback: ConfigReadback | None
    error: str = ''

    @property
    def ok(self) -> bool:
        """Tell whether a complete configuration was read."""
        return self.readback is not None and self.readback.config is not None


def _text(value: Any, name: str = '') -> str:
    word = sentinel_text(name, value)  # off / never, as the Monitor shows it
    if word is not None:
        return f'{word} ({value})'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (tuple, list)):
        return ', '.join(str(v) for v in value)
    return f'{value:g}' if isinstance(value, float) else str(value)


class ConfigReader:
    """The read-back state of one EVMS3; its lock is the device's (the bus thread's)."""

    def __init__(self, lock: threading.Lock, request: Frame) -> None:
        self._cv = threading.Condition(lock)
        self._request = request
        self._last: dict[int, tuple[ConfigReport, float]] = {}  # ID -> (packet, clock())
        self._waiting: dict[int, ConfigReport] | None = None
        self._malformed: list[str] = []

    # --- bus thread (device lock held) ----------------------------------------------------
    def offer(self, report: ConfigReport, now: float) -> None:
        """Take one decoded packet of 52..56."""
        self._last[report.arbitration_id] = (report, now)
        if self._waiting is not None:
            self._waiting[report.arbitration_id] = report
            self._cv.notify_all()

    def offer_malformed(self, reason: str) -> None:
        """Remember a malformed 52..56 frame for the read waiting now (its answer fails)."""
        if self._waiting is not None:
            self._malformed.append(reason)

    # --- service thread (device lock NOT held) ----------------------------------------------
    def read(self, send: SendFrame, timeout: float) -> ReadResult:
        """
        Send ID 51 through ``send`` and wait up to timeout s for 52..56.

        Never raises: a refused send, a read already waiting, or a partial answer come back
        as a ReadResult without a configuration and a reason naming what is missing.
        """
        with self._cv:
            if self._waiting is not None:
                return ReadResult(None, 'another read_config is waiting for the EVMS3')
            waiting: dict[int, ConfigReport] = {}
            self._waiting, self._malformed = waiting, []
        try:
            ok, why = send(self._request)
            if not ok:
                return ReadResult(None, f'ID 51 was not sent: {why}')
            deadline = time.monotonic() + timeout
            with self._cv:
                while len(waiting) < len(READBACK_IDS) and not cancel_reason(send):
                    left = deadline - time.monotonic()
                    if left <= 0:
                        break
                    self._cv.wait(min(left, CANCEL_POLL))  # a transition may end the call
                got, malformed = dict(waiting), list(self._malformed)
            ended = cancel_reason(send)
            if ended and len(got) < len(READBACK_IDS):
                return ReadResult(None, f'cancelled by {ended} while waiting for IDs 52..56')
        finally:
            with self._cv:
                self._waiting = None
        readback = ConfigReadback.join(got.values())
        if readback.config is None:
            reason = (f'no complete answer within {timeout:g} s: ' + readback.summary()
                      + ''.join(f'; {m}' for m in malformed))
            return ReadResult(readback, reason)
        return ReadResult(readback)

    # --- executor (device lock held) --------------------------------------------------------
    def _complete(self) -> bool:
        times = [seen for _, seen in self._last.values()]
        return (len(self._last) == len(READBACK_IDS)
                and max(times) - min(times) <= ANSWER_WINDOW)

    def last_values(self) -> dict[str, Any]:
        """Return the values of the last complete answer seen on the bus ({} if none)."""
        if not self._last or not self._complete():
            return {}
        return ConfigReadback.join(report for report, _ in self._last.values()) \
            .parameter_values()

    def values(self, now: float) -> dict[str, str]:
        """Diagnostics values: the last complete answer seen on the bus, and its age."""
        if not self._last:
            return {}
        times = [seen for _, seen in self._last.values()]
        if not self._complete():
            missing = [i for i in READBACK_IDS if i not in self._last]
            text = ('incomplete: missing ' + ', '.join(
                f'ID {i} ({READBACK_NAMES[i]})' for i in missing) if missing
                else 'incomplete: packets of different answers')
            return {'config read back': text}
        readback = ConfigReadback.join(report for report, _ in self._last.values())
        values = {'config read back': f'{now - max(times):.1f} s ago (IDs 52..56)'}
        for name, value in readback.parameter_values().items():
            unit = _UNITS.get(name, '')
            values[f'config {name}' + (f' ({unit})' if unit else '')] = _text(value, name)
        return values


def read_back(name: str, reader: ConfigReader, port: CallPort, allowed: bool,
              timeout: float) -> tuple[bool, str]:
    """
    Run read_config: ask with ID 51, then set every config.* parameter from the answer.

    Refused (nothing sent) unless ``allowed`` (``<name>.config_request``): ID 51 is also a
    ZEVA motor controller's throttle frame. A partial answer sets nothing.
    """
    if not allowed:
        return False, (
            f'{name}: read_config refused: {name}.config_request is false. ID 51 asks the '
            'EVMS3 for its configuration, but a ZEVA motor controller takes ID 51 as its '
            f'throttle frame: set the parameter {name}.config_request to true only if no ZEVA '
            'motor controller is on this bus; nothing was sent')
    # the port waits for the bus outside the gate's batch lock, then sends ID 51 under it
    result = reader.read(port, timeout)
    readback = result.readback
    if readback is None or not result.ok:
        return False, f'{name}: read_config failed: {result.error}; nothing was set'
    values = readback.parameter_values()
    ok, reason = port.set_config({f'config.{key}': value for key, value in values.items()})
    if not ok:
        return False, (f'{name}: read_config: the EVMS3 answered, but its values cannot be '
                       f'set: {reason}; nothing was set')
    return True, (f'{name}: read_config: {readback.summary()}; set {len(values)} parameters '
                  f'{name}.config.*')
