# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Timed values and counter health: the freshness and counter rules every device shares.

A device keeps each reading with the ``Device.clock()`` it arrived at and shows it only
while it is younger than its maximum age: an expired value reads as absent (None) or NaN,
never as the last number, so a stopped frame shows as a gap and not as a live flat line.
Before this module every device wrote that rule by hand, in six slightly different shapes.

``CounterHealth`` is the rolling-counter check of the AMS status (8 bit) and of each IVT-S
result (4 bit, advancing by a step learned per result): a repeated counter is a stuck
sender, a skipped one lost frames; an anomaly stays visible until enough good frames
followed it. After a silence longer than the value's
maximum age a restarted counter is no anomaly (the sender may have been power-cycled).

No locking here: the owning device calls these with its lock held.
"""
from __future__ import annotations

import math
from typing import Callable, Generic, Hashable, Iterable, Sequence, TypeVar

NAN = math.nan
NEVER = -math.inf  # the arrival time of a value never received: older than any max age

K = TypeVar('K', bound=Hashable)
V = TypeVar('V')


class TimedStore(Generic[K, V]):
    """The latest value per key with the clock() it came at; too old reads as None."""

    __slots__ = ('_latest',)

    def __init__(self) -> None:
        self._latest: dict[K, tuple[V, float]] = {}

    def put(self, key: K, value: V, now: float) -> None:
        """Keep value as the latest of key, received at now."""
        self._latest[key] = (value, now)

    def replace(self, key: K, value: V, now: float) -> float:
        """Keep value as the latest of key, received at now; return the previous seen()."""
        entry = self._latest.get(key)
        self._latest[key] = (value, now)
        return NEVER if entry is None else entry[1]

    def get(self, key: K, now: float, max_age: float) -> V | None:
        """Return the latest value of key if it came within max_age, else None."""
        entry = self._latest.get(key)
        return entry[0] if entry is not None and now - entry[1] <= max_age else None

    def entry(self, key: K) -> tuple[V, float] | None:
        """Return (latest value, the clock() it came at) of key, None before any."""
        return self._latest.get(key)

    def latest(self, key: K) -> V | None:
        """Return the latest value of key whatever its age (None before any)."""
        entry = self._latest.get(key)
        return None if entry is None else entry[0]

    def seen(self, key: K) -> float:
        """Return the clock() the latest value of key came at (NEVER before any)."""
        entry = self._latest.get(key)
        return NEVER if entry is None else entry[1]

    def keys(self) -> list[K]:
        """Return every key ever received, in arrival order of its first value."""
        return list(self._latest)

    def __contains__(self, key: object) -> bool:
        return key in self._latest

    def split(self, now: float, max_age: Callable[[K], float]
              ) -> tuple[dict[K, V], dict[K, float]]:
        """Split into ({key: fresh value}, {expired key: seconds silent})."""
        fresh: dict[K, V] = {}
        expired: dict[K, float] = {}
        for key, (value, seen) in self._latest.items():
            silent = now - seen
            if silent > max_age(key):
                expired[key] = silent
            else:
                fresh[key] = value
        return fresh, expired

    def fresh(self, now: float, max_age: float) -> dict[K, V]:
        """Return {key: value} of every key whose latest value came within max_age."""
        return {key: value for key, (value, seen) in self._latest.items()
                if now - seen <= max_age}


class TimedSpans:
    """
    Float values in fixed spans (one span per frame), each NaN once its frame is too old.

    Cells and temperatures come in frames of a few values each; a frame that stops makes
    its own values unknown, not its neighbours'.
    """

    __slots__ = ('starts', 'lengths', 'values', 'seen')

    def __init__(self, lengths: Sequence[int]) -> None:
        self.lengths = tuple(lengths)
        self.starts = tuple(sum(self.lengths[:i]) for i in range(len(self.lengths)))
        self.values = [NAN] * sum(self.lengths)
        self.seen = [NEVER] * len(self.lengths)

    @classmethod
    def uniform(cls, length: int, count: int) -> TimedSpans:
        """Make count spans of length values each."""
        return cls([length] * count)

    def put(self, span: int, values: Iterable[float], now: float) -> None:
        """Keep the values of one span (its frame), received at now."""
        start = self.starts[span]
        self.values[start:start + self.lengths[span]] = values
        self.seen[span] = now

    def put_elements(self, first: int, values: list[float], now: float) -> None:
        """Keep consecutive spans of ONE value each (spans first..), received at now."""
        end = first + len(values)
        self.values[first:end] = values
        self.seen[first:end] = [now] * len(values)

    def read(self, now: float, max_age: float, spans: int | None = None) -> list[float]:
        """Return the values of the first spans (all: None), NaN where a span is too old."""
        if spans is None or spans == len(self.lengths):
            count, seen, end = len(self.lengths), self.seen, len(self.values)
        else:
            count, seen = spans, self.seen[:spans]
            end = self.starts[count - 1] + self.lengths[count - 1] if count else 0
        if not count:
            return []
        if now - min(seen) <= max_age:
            return self.values[:end]  # every span fresh: the usual case, one slice
        out = self.values[:end]
        for span in range(count):
            if now - self.seen[span] > max_age:
                start = self.starts[span]
                out[start:start + self.lengths[span]] = [NAN] * self.lengths[span]
        return out

    def newest(self) -> float:
        """Return the clock() of the most recent span (NEVER before any)."""
        return max(self.seen, default=NEVER)


class CounterHealth:
    """
    Health of a rolling message counter: repeats (stuck), skips (lost frames), recovery.

    ``modulus`` is the counter's range (256 for 8 bits, 16 for 4 bits); an anomaly stays
    ``in_trouble`` until ``recovery`` frames with the expected counter followed it.

    ``step`` is how far the counter advances from one frame to the next: 1 for a counter of
    frames (the AMS), None for one that counts something else at a constant rate (the
    IVT-S counts its measurement cycles, so a result sent every 100 ms advances by 5): the
    step is then learned from the counter itself. An advance of whole steps (within one turn
    of the counter) is frames lost, any other advance is out of step; both are anomalies.
    The first advance is the step until the next frame advancing by it confirms it; before
    that an advance out of step replaces it, after that only ``RELEARN`` consecutive frames
    with one new advance do. A counter that does not advance is always an anomaly, as is
    one that keeps changing its advance.
    """

    RELEARN = 3  # consecutive frames with one new advance that replace a confirmed step

    __slots__ = ('modulus', 'recovery', 'learn', 'step', 'confirmed', 'candidate',
                 'candidate_run', 'last', 'repeat_run', 'repeats', 'jumps', 'lost',
                 'good_streak')

    def __init__(self, modulus: int, recovery: int, step: int | None = 1) -> None:
        self.modulus = modulus
        self.recovery = recovery
        self.learn = step is None
        self.step = step  # the advance per frame (None: not learned yet)
        self.confirmed = not self.learn  # a fixed step needs no confirmation
        self.candidate: int | None = None  # a new advance seen after a confirmed step
        self.candidate_run = 0  # consecutive frames with that new advance
        self.last: int | None = None  # the previous counter (None before the first)
        self.repeat_run = 0  # consecutive frames repeating the counter now
        self.repeats = 0  # frames that repeated the previous counter, in total
        self.jumps = 0  # frames whose counter skipped, or advanced by another step
        self.lost = 0  # frames the skips say were lost, in total
        self.good_streak = recovery  # frames with the expected counter since an anomaly

    def observe(self, counter: int, continuous: bool) -> None:
        """
        Take the counter of the next frame.

        ``continuous`` says the previous frame is still fresh; after a longer silence the
        counter may restart anywhere, so only the repeat run ends.
        """
        last, self.last = self.last, counter
        if last is None or not continuous:
            self.repeat_run = 0
            return
        advance = (counter - last) % self.modulus
        if advance == 0:
            self.repeat_run += 1
            self.repeats += 1
            self.good_streak = 0
            return
        self.repeat_run = 0
        if self.step is None:  # the first advance: the step until the next frame says
            self.step = advance
            self.good_streak += 1
        elif advance == self.step:
            self.confirmed = True
            self.candidate, self.candidate_run = None, 0
            self.good_streak += 1
        else:
            self._jump(advance, self.step)

    def _jump(self, advance: int, step: int) -> None:
        """Count an advance other than the step: frames lost, or a counter out of step."""
        whole = advance % step == 0  # whole steps: frames lost
        self.jumps += 1
        self.lost += advance // step - 1 if whole else 0
        self.good_streak = 0
        if not self.learn:
            return
        if not self.confirmed:
            if not whole:  # the first advance was no step of this counter
                self.step = advance
            return
        if advance == self.candidate:
            self.candidate_run += 1
        else:
            self.candidate, self.candidate_run = advance, 1
        if self.candidate_run >= self.RELEARN:  # the sender changed its rate
            self.step, self.candidate, self.candidate_run = advance, None, 0

    def restart(self) -> None:
        """
        Forget the last counter and a learned step (the sender's rate was changed).

        The totals and the recovery of an earlier anomaly stay.
        """
        self.last = None
        self.repeat_run = 0
        if self.learn:
            self.step, self.confirmed, self.candidate, self.candidate_run = None, False, None, 0

    @property
    def recovering(self) -> bool:
        """Tell whether fewer than ``recovery`` good frames followed the last anomaly."""
        return self.good_streak < self.recovery

    @property
    def in_trouble(self) -> bool:
        """Tell whether a recent anomaly (repeat or skip) still lacks its good frames."""
        return (self.repeats or self.jumps) > 0 and self.recovering
