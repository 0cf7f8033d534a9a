# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Two batteries in parallel on one bus, and the scenarios that make their pack misbehave.

``simulator --pack`` (and ``demo --pack``) play the pair of config/pack.yaml: a standard-form
BMS16 (29-bit IDs from 30, its fixed 40 and 301..312) on 16 LiFePO4 cells beside an EVMS3
built with 11-bit IDs (base 100: 100..111, its BMS12 modules on 300..314 11-bit) on 13 NMC
cells in two BMS12 modules of 7 and 6, both about 52 V, on one 250 kbit/s bus. Two ZEVA
systems cannot share one ID space: the BMS16's cells and current sit on the EVMS3's fixed
BMS12 and current-sensor IDs, so the EVMS3 is the 11-bit build. Each member carries half of
the drive profile (the pack's load shared).

Scenarios (``--scenario NAME[@START]``, START in s after the first tick, default 2):

- ``drift``: the EVMS3 loses DRIFT_AH_PER_S for DRIFT_SECONDS (a weak member taking more
  than its share): its voltage falls about 2 V below the BMS16's, past the pack's
  ``max_voltage_difference`` (1.5 V), and stays there.
- ``silence``: the EVMS3 sends nothing for SILENCE_SECONDS, then comes back: stale, then
  present again.
- ``cell_over``: the EVMS3's first cell sits CELL_OVER_V above the others for
  CELL_OVER_SECONDS (about 4.3 V, past the MSL of config/pack.yaml's
  ``cell_voltage_max`` of 4.20 V for longer than the 0.5 s debounce), then comes back inside:
  the pack's MSL event stays latched until ``pack/clear_events``.
"""
from __future__ import annotations

from typing import Callable

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.sim.base import SimDevice
from ams_can_bridge.sim.bms16_std import Bms16StdSimulator
from ams_can_bridge.sim.evms3 import Evms3Simulator
from ams_can_bridge.sim.profiles import drive_current_a

BMS16_BASE_ID = 30           # 29-bit, ZEVA's default
EVMS3_BASE_ID = 100          # 11-bit: clear of the read-back IDs 51..56 and the BMS12 IDs
EVMS3_CELLS = (7, 6)         # 13 NMC cells: about the voltage of 16 LiFePO4 cells
DEFAULT_START_S = 2.0
DRIFT_AH_PER_S = 2.0
DRIFT_SECONDS = 10.0         # 20 Ah of 100: 13 cells x 0.85 V x 0.2 = 2.2 V lower
SILENCE_SECONDS = 4.0        # > the members' stale_timeout of 1.25 s
CELL_OVER_V = 0.3
CELL_OVER_SECONDS = 3.0      # > the pack's debounce of 0.5 s
SCENARIOS = ('drift', 'silence', 'cell_over')


def _half(t: float) -> float:
    return drive_current_a(t) / 2.0


def _from_first_call(current_fn: Callable[[float], float]) -> Callable[[float], float]:
    """Return current_fn on the time since the first call, the EVMS3 simulator's own time base."""
    start: list[float] = []

    def current(now: float) -> float:
        if not start:
            start.append(now)
        return current_fn(now - start[0])
    return current


def build_pair(current_fn: Callable[[float], float] = _half) -> list[SimDevice]:
    """
    Return the BMS16 (instance ``bms16``) and the EVMS3 (``evms3``) of config/pack.yaml.

    Both take current_fn on the time since their first tick (the BMS16's own is the clock's
    time), so two members in parallel carry the same current at the same moment.
    """
    return [Bms16StdSimulator(name='bms16', base_id=BMS16_BASE_ID,
                              current_fn=_from_first_call(current_fn)),
            Evms3Simulator(name='evms3', base_id=EVMS3_BASE_ID, extended_id=False,
                           bms12_modules=len(EVMS3_CELLS), cells_per_module=list(EVMS3_CELLS),
                           current_fn=current_fn)]


def parse_scenario(text: str) -> tuple[str, float]:
    """Parse NAME[@START] (ConfigError, a ValueError, naming the choices)."""
    name, sep, start = text.partition('@')
    if name not in SCENARIOS:
        raise ConfigError(f'scenario {text!r}: use one of {", ".join(SCENARIOS)}, '
                          'optionally @START (s), e.g. cell_over@3')
    try:
        seconds = float(start) if sep else DEFAULT_START_S
    except ValueError:
        raise ConfigError(f'scenario {text!r}: START must be seconds, e.g. {name}@3') from None
    if not seconds >= 0:
        raise ConfigError(f'scenario {text!r}: START must be >= 0 s')
    return name, seconds


class PairScenario(SimDevice):
    """
    Sends nothing: at each tick (listed before the pair) it steers the EVMS3 of the pair.

    Time counts from its first tick, as the simulators' own profiles do.
    """

    TYPE = 'scenario'

    def __init__(self, devices: list[SimDevice],
                 scenarios: list[tuple[str, float]]) -> None:
        super().__init__('scenario')
        evms3 = next((d for d in devices if isinstance(d, Evms3Simulator)), None)
        if evms3 is None:
            raise ConfigError('a pack scenario needs the pair: use --pack')
        self.evms3 = evms3
        self.scenarios = list(scenarios)
        self._t0: float | None = None
        self._last: float | None = None

    def _active(self, name: str, start: float, elapsed: float) -> bool:
        length = {'drift': DRIFT_SECONDS, 'silence': SILENCE_SECONDS,
                  'cell_over': CELL_OVER_SECONDS}[name]
        return start <= elapsed < start + length

    def tick(self, now: float) -> list[Frame]:
        """Apply the scenarios due at ``now`` to the EVMS3; no frames."""
        if self._t0 is None:
            self._t0 = now
        elapsed = now - self._t0
        dt = 0.0 if self._last is None else max(0.0, now - self._last)
        self._last = now
        silent = over = False
        for name, start in self.scenarios:
            active = self._active(name, start, elapsed)
            if name == 'drift' and active:
                self.evms3.remaining_ah = max(0.0, self.evms3.remaining_ah
                                              - DRIFT_AH_PER_S * dt)
            silent = silent or (name == 'silence' and active)
            over = over or (name == 'cell_over' and active)
        # Only the switches a scenario owns: a --fault on the other ones stays as given.
        names = {name for name, _ in self.scenarios}
        if 'silence' in names:
            self.evms3.faults.silent = silent
        if 'cell_over' in names:
            self.evms3.faults.drift_cell = 0
            self.evms3.faults.cell_drift_v = CELL_OVER_V if over else 0.0
        return []
