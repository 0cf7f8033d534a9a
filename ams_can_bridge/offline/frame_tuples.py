# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A CAN frame as log2bag's readers hand it on: a plain tuple, not a ``can.Message``.

``Frame`` is (timestamp, arbitration_id, data, is_extended_id, is_error_frame,
is_remote_frame): what the converter takes of a frame. ``LogFrames.frames()`` yields them
(``offline/log_frames.py``), from the own readers of candump ``.log`` (``candump_frames``)
and ``.blf`` (``blf_frames``), or from python-can's messages for the other formats.
"""
from __future__ import annotations

from typing import Optional, Protocol, Tuple

import can

Frame = Tuple[float, int, bytes, bool, bool, bool]


def message_frame(msg: can.Message) -> Frame:
    """Return python-can's message as a ``Frame``."""
    return (msg.timestamp, msg.arbitration_id, bytes(msg.data), msg.is_extended_id,
            msg.is_error_frame, msg.is_remote_frame)


class Counts(Protocol):
    """What an own reader counts into: ``LogFrames``."""

    bad: int
    last_bad: str
    cut_line: Optional[str]

    def accepted(self, msg: can.Message) -> bool:
        """Tell whether python-can's message is a frame (counted as a bad entry when not)."""

    def bad_stamp(self, arbitration_id: int, stamp: float, problem: str) -> None:
        """Count an entry whose timestamp is no time."""
