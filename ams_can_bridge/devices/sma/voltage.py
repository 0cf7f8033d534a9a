# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
How an SMA device reads 0x356's voltage: ``<name>.voltage_scale`` or the battery's evidence.

``auto`` (the default) decides with ``protocols.sma_scale.decide_voltage_scale`` from the
battery's own 0x351 limits and cell voltages (doc/protocols.md section 5.2). Until that
evidence has come, the voltage is unknown; a decision the evidence settles is kept. A
battery whose evidence never settles it within the wait gets SMA's 0.01 V with a WARN
naming the parameter.
"""
from __future__ import annotations

from dataclasses import dataclass

from ams_can_bridge.protocols.sma import SmaLimits
from ams_can_bridge.protocols.sma_scale import (
    decide_voltage_scale, ScaleDecision, SMA_VOLTAGE_SCALE, VOLTAGE_SCALES)

AUTO = 'auto'
SCALE_CHOICES = (AUTO, *(f'{s:g}' for s in VOLTAGE_SCALES))


@dataclass(frozen=True)
class ScaleInUse:
    """The scale to read 0x356 with now (None: unknown yet), why, and a warning if any."""

    scale: float | None
    text: str
    warning: str = ''


class VoltageScale:
    """The 0x356 voltage scale of one device: fixed by its parameter, or from evidence."""

    def __init__(self, parameter: str, setting: str, wait: float) -> None:
        self.parameter = parameter  # '<name>.voltage_scale', named in the warning
        self.setting = setting
        self.wait = wait  # s after the first 0x356 without evidence before assuming 0.01 V
        self.settled: ScaleDecision | None = None
        self.first_battery: float | None = None

    def reset(self, setting: str, wait: float) -> None:
        """Start again with a new setting (a configure): the evidence is weighed anew."""
        self.setting, self.wait = setting, wait
        self.settled = None
        self.first_battery = None

    @property
    def undecided(self) -> bool:
        """Tell whether the evidence is still being weighed (auto, not settled yet)."""
        return self.setting == AUTO and self.settled is None

    def saw_battery(self, now: float) -> None:
        """Note a 0x356 (the wait for evidence runs from the first)."""
        if self.first_battery is None:
            self.first_battery = now

    def in_use(self, voltage_raw: int | None, limits: SmaLimits | None,
               cells_v: tuple[float, float] | None, now: float) -> ScaleInUse:
        """Return the scale for a 0x356 of voltage_raw, given the fresh evidence now."""
        if self.setting != AUTO:
            return ScaleInUse(float(self.setting), f'{self.setting} V/bit ({self.parameter})')
        if self.settled is None and voltage_raw is not None:
            decision = decide_voltage_scale(voltage_raw, limits, cells_v)
            if decision.scale is not None:
                self.settled = decision
            elif self.first_battery is not None and now - self.first_battery >= self.wait:
                return self._assumed(decision, limits)
            else:
                return ScaleInUse(None, f'unknown until 0x351 (auto): {decision.reason}')
        if self.settled is None:
            return ScaleInUse(None, 'unknown until 0x351 and 0x356 (auto)')
        return ScaleInUse(self.settled.scale,
                          f'{self.settled.scale:g} V/bit (auto: {self.settled.reason})')

    def _assumed(self, decision: ScaleDecision, limits: SmaLimits | None) -> ScaleInUse:
        why = (decision.reason if limits is not None
               else f'no 0x351 voltage limits within {self.wait:g} s')
        return ScaleInUse(SMA_VOLTAGE_SCALE, f'{SMA_VOLTAGE_SCALE:g} V/bit (assumed: {why})',
                          f"0x356 voltage scale assumed SMA's {SMA_VOLTAGE_SCALE:g} V ({why}): "
                          f'set {self.parameter} to 0.01 or 0.1 if the voltage is 10x off')
