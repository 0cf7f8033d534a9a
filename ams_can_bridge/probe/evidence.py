# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What a recogniser hands back: a candidate device with its evidence, settings and confidence.

A ``Setting`` is one parameter of the instance as the params file will carry it: decided
by the evidence (written, with the evidence as its comment) or not (written commented out,
with what to check). A ``Candidate`` claims the observed IDs it explains; two candidates
claiming one ID are a conflict (``recognise.py`` keeps one and says so).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any

from ams_can_bridge.device_set import format_ids
from ams_can_bridge.probe.traffic import IdTraffic, Key
from ams_can_bridge.protocols import orion_bms2

HIGH = 0.8    # confidence from here: 'high'
MEDIUM = 0.5  # from here: 'medium', written to the params file; below: reported only
WEAK = 0.35   # below: not even reported as a candidate (its IDs stay unplaced)
STALE_MARGIN = 1.1  # a period this much over the default's fifth is a slower sender, not jitter


def sender_proven_elsewhere(entry: IdTraffic) -> str:
    """
    Name the device whose checksum every frame of this ID carries ('' if none).

    Such frames prove their sender: they are no evidence for another device that uses the
    same ID (Orion's cell broadcast 0x36 is also an EVMS3 read-back ID, 54).
    """
    frames = entry.payloads
    if (entry.can_id in orion_bms2.CHECKSUM_IDS and not entry.extended and len(frames) >= 2
            and all(orion_bms2.checksum_right(entry.can_id, d) for d in frames)):
        return 'an Orion BMS 2 (its checksum byte is right in every frame)'
    return ''


@dataclass
class Setting:
    """One '<instance>.<key>' value and why (decided) or what to check (not decided)."""

    key: str
    value: Any
    why: str
    decided: bool = True


@dataclass
class Candidate:
    """A device a recogniser found, with everything that made it think so."""

    type: str                   # the bridge's device type (ams, ivt_s, evms3, bms16, sma, dbc)
    name: str                   # the instance name it suggests (made unique on output)
    title: str                  # what it is, for people: 'AMS at base 0x300'
    confidence: float           # 0..1
    ids: frozenset[Key]         # the observed IDs it explains
    evidence: list[str] = field(default_factory=list)
    settings: list[Setting] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # warnings, what the bridge cannot do
    facts: dict[str, Any] = field(default_factory=dict)  # for cross-device decisions
    writable: bool = True       # False: reported only, never in the params file
    user_given: bool = False    # from --dbc/--mapping: wins a tie
    # IDs it could explain but leaves to another candidate (kept both: a conflict saying so)
    deferred: list[tuple[Candidate, frozenset[Key], str]] = field(default_factory=list)

    @property
    def level(self) -> str:
        """Say the confidence in a word."""
        if self.confidence >= HIGH:
            return 'high'
        return 'medium' if self.confidence >= MEDIUM else 'low'

    @property
    def written(self) -> bool:
        """Tell whether the params file lists it in devices."""
        return self.writable and self.confidence >= MEDIUM

    def setting(self, key: str) -> Setting | None:
        """Return the setting of a key, None if it has none."""
        return next((s for s in self.settings if s.key == key), None)

    def set(self, key: str, value: Any, why: str, decided: bool = True) -> None:
        """Add or replace the setting of a key."""
        self.settings = [s for s in self.settings if s.key != key]
        self.settings.append(Setting(key, value, why, decided))

    def ids_text(self) -> str:
        """List the IDs it explains, runs collapsed ('0x12C-0x130; ... (29-bit)')."""
        return format_ids(self.ids).partition(' ')[2]


@dataclass
class Conflict:
    """
    Two candidates for the same IDs: the one kept and the one set aside.

    With a ``decision``, both devices stay and the IDs are the kept one's (a shipped
    profile's DBC describes a sensor the BMS reads): the decision says so.
    """

    kept: Candidate
    dropped: Candidate
    ids: frozenset[Key]
    decision: str = ''

    def text(self) -> str:
        """Say what was decided and why."""
        common = format_ids(self.ids).partition(' ')[2]
        return (f'{self.dropped.title} ({self.dropped.level}, {self.dropped.confidence:.2f}) '
                f'and {self.kept.title} ({self.kept.level}, {self.kept.confidence:.2f}) both '
                f'explain {common}: ' + (self.decision or f'kept {self.kept.title}'))


def stale_setting(candidate: Candidate, period_s: float, default_s: float,
                  what: str) -> None:
    """
    Write stale_timeout when the primary frame comes slower than the default allows.

    The bridge's default is 5 x the device's usual period; a sender set to a slower cycle
    would be STALE between its own frames: then 5 x the observed period, rounded up.
    """
    if period_s == period_s and 5 * period_s > STALE_MARGIN * default_s:
        value = max(math.ceil(50 * period_s) / 10, default_s)
        candidate.set('stale_timeout', value,
                      f'{what} every {period_s:.3g} s: 5 x that (the default {default_s:g} s '
                      'would go STALE between frames)')
