# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Time to empty / to full from the mean current over a window (dbus-serialbattery's time-to-go).

The mean is taken over the reports of the last ``window`` seconds, so a short load peak does not
make the figure jump. Under 0.1 A of mean current the figure would be meaningless (and huge):
NaN, as it is in the other direction and while the charge is unknown.
"""
from __future__ import annotations

import collections
import math

MIN_CURRENT = 0.1  # A: below this mean current, no time-to-go
SECONDS_PER_HOUR = 3600.0


class TimeToGo:
    """A window of (stamp, current) samples and the two times derived from it."""

    def __init__(self, window: float = 60.0) -> None:
        """Keep the samples of the last ``window`` seconds."""
        self.window = window
        self._samples: collections.deque[tuple[float, float]] = collections.deque()
        self._sum = 0.0
        self._unknown = 0

    def add(self, stamp: float, current: float) -> None:
        """Take one pack current (A, ROS sign) at ``stamp``; drop the samples out of window."""
        self._samples.append((stamp, current))
        if math.isnan(current):
            self._unknown += 1
        else:
            self._sum += current
        while self._samples and self._samples[0][0] < stamp - self.window:
            _, old = self._samples.popleft()
            if math.isnan(old):
                self._unknown -= 1
            else:
                self._sum -= old
        if not self._unknown and len(self._samples) > 1:
            # A running sum drifts after many additions: recompute it exactly now and then.
            if len(self._samples) % 1024 == 0:
                self._sum = math.fsum(c for _, c in self._samples)

    def mean(self) -> float:
        """Return the mean current of the window (NaN with an unknown sample or none)."""
        if self._unknown or not self._samples:
            return math.nan
        return self._sum / len(self._samples)

    def times(self, charge: float, capacity: float) -> tuple[float, float]:
        """Return (time_to_empty, time_to_full) in s from the charge and capacity in Ah."""
        mean = self.mean()
        empty = full = math.nan
        if math.isfinite(mean) and math.isfinite(charge):
            if mean <= -MIN_CURRENT:
                empty = charge * SECONDS_PER_HOUR / -mean
            elif mean >= MIN_CURRENT and math.isfinite(capacity):
                full = max(capacity - charge, 0.0) * SECONDS_PER_HOUR / mean
        return empty, full
