# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What every CAN ID showed while probe listened: count, lengths, timing and sample payloads.

One pass over the frames, a few dictionary operations a frame (probe reads a log at least
as fast as ``log2bag``: bench/bench_probe.py). The recognisers work on these summaries
afterwards: the first ``SAMPLES`` payloads of each ID (counters, byte order, plausible
values) and the first payload for each value of byte 0 (a multiplexer or bank/group byte
cycles through its values: each is kept once, however rare).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import statistics
from typing import Iterable, Iterator

SAMPLES = 64  # first payloads kept per ID
# IDs kept at most: a battery bus has tens to a few hundred; beyond this the frames of new
# IDs are only counted, so probe's memory is bounded by the IDs kept, never by the frames
# (a million random frames would otherwise keep a summary per random ID).
MAX_IDS = 2048
Key = tuple[int, bool]  # (arbitration ID, 29-bit)
PERIODIC_SHARE = 0.6  # of the gaps within half to twice the median: a sender's cycle


@dataclass(eq=False)
class IdTraffic:
    """Everything probe keeps of one CAN ID."""

    can_id: int
    extended: bool
    count: int = 0
    first: float = math.nan
    last: float = math.nan
    dlcs: dict[int, int] = field(default_factory=dict)
    samples: list[tuple[float, bytes]] = field(default_factory=list)
    by_byte0: dict[int, bytes] = field(default_factory=dict)  # -1: frames without data

    @property
    def key(self) -> Key:
        """Return (ID, 29-bit)."""
        return self.can_id, self.extended

    @property
    def payloads(self) -> list[bytes]:
        """Return the sampled payloads, oldest first."""
        return [data for _, data in self.samples]

    @property
    def rate_hz(self) -> float:
        """Return frames per second over the time it was heard (NaN: heard once)."""
        span = self.last - self.first
        return (self.count - 1) / span if self.count > 1 and span > 0 else math.nan

    @property
    def period_s(self) -> float:
        """Return the median gap between the sampled frames (NaN: fewer than two)."""
        stamps = [stamp for stamp, _ in self.samples]
        gaps = [b - a for a, b in zip(stamps, stamps[1:]) if b > a]
        return statistics.median(gaps) if gaps else math.nan

    @property
    def periodic(self) -> bool:
        """
        Tell whether the sampled frames come on a cycle, as a device sends them.

        At least three frames, and most gaps (PERIODIC_SHARE) within half to twice their
        median: frames at random times (noise, a fuzzer) have exponential gaps, of which
        under half lie there; a device's cycle with jitter has nearly all.
        """
        stamps = [stamp for stamp, _ in self.samples]
        gaps = [b - a for a, b in zip(stamps, stamps[1:]) if b > a]
        if len(gaps) < 2:
            return False
        median = statistics.median(gaps)
        near = sum(1 for g in gaps if median / 2 <= g <= 2 * median)
        return near >= PERIODIC_SHARE * len(gaps)

    @property
    def dlc(self) -> int:
        """Return the most frequent data length."""
        return max(self.dlcs, key=lambda n: self.dlcs[n])

    def label(self) -> str:
        """Return the ID as candump writes it: 3 hex digits, 8 for a 29-bit ID."""
        return id_label(self.can_id, self.extended)


def id_label(can_id: int, extended: bool) -> str:
    """Return an ID as candump writes it (0x1E / 0x0000001E told apart by width)."""
    return f'0x{can_id:08X}' if extended else f'0x{can_id:03X}'


def rate_text(rate_hz: float) -> str:
    """Say a rate as people say it: '10 Hz', '0.2 Hz', 'once'."""
    if not math.isfinite(rate_hz):
        return 'once'
    return f'{rate_hz:.3g} Hz'


class Traffic:
    """The per-ID summaries of one listening session, filled frame by frame."""

    def __init__(self) -> None:
        """Start empty."""
        self.ids: dict[Key, IdTraffic] = {}
        self.frames = 0
        self.error_frames = 0
        self.remote_frames = 0
        self.first = math.nan
        self.last = math.nan
        self.unkept_frames = 0  # frames of new IDs once MAX_IDS were kept

    def add(self, can_id: int, extended: bool, data: bytes | bytearray, stamp: float) -> None:
        """Take one data frame."""
        key = (can_id, extended)
        entry = self.ids.get(key)
        if entry is None:
            if self.frames == 0:
                self.first = stamp
            if len(self.ids) >= MAX_IDS:
                self.frames += 1
                self.last = stamp
                self.unkept_frames += 1
                return
            entry = self.ids[key] = IdTraffic(can_id, extended, first=stamp)
        self.frames += 1
        self.last = stamp
        entry.count += 1
        entry.last = stamp
        length = len(data)
        entry.dlcs[length] = entry.dlcs.get(length, 0) + 1
        if entry.count <= SAMPLES:
            entry.samples.append((stamp, bytes(data)))
        byte0 = data[0] if length else -1
        if byte0 not in entry.by_byte0:
            entry.by_byte0[byte0] = bytes(data)

    def get(self, can_id: int, extended: bool = False) -> IdTraffic | None:
        """Return the summary of an ID, None if it was never heard."""
        return self.ids.get((can_id, extended))

    def __iter__(self) -> Iterator[IdTraffic]:
        """Iterate the IDs heard, in ID order (11-bit first)."""
        return iter(sorted(self.ids.values(), key=lambda t: (t.extended, t.can_id)))

    def of_width(self, extended: bool) -> Iterable[IdTraffic]:
        """Iterate the IDs of one width."""
        return (t for t in self if t.extended == extended)

    @property
    def span_s(self) -> float:
        """Return the time from the first frame to the last."""
        return self.last - self.first if self.frames else 0.0
