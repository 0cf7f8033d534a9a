# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What the EVMS3 and the standard-form BMS16 share on the bus (doc/protocols.md 3 and 6).

Both send the EVMS3 status layout at 4 Hz (byte 5 = 255 marks a BMS16) and their cells in
BMS12 module frames (IDs 300 + 10 m + t, four cells of uint16 mV in t = 1, 2, 3). A cell
input with nothing wired reads 0 V: the cells of a module are those that read more.
"""
from __future__ import annotations

from dataclasses import dataclass
from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.probe.evidence import sender_proven_elsewhere
from ams_can_bridge.probe.traffic import IdTraffic, Traffic
from ams_can_bridge.protocols.bms12 import BMS12_BASE_ID, BMS12_MAX_MODULES, decode_cells
from ams_can_bridge.protocols.evms3 import Evms3Status, generated, LAYOUTS

STATUS_LENGTH = LAYOUTS['EVMS3_Status'].length
FOUR_HZ = (0.2, 0.32)  # s: the status period of a ZEVA core (4 Hz), with jitter
CELLS_PER_BMS12 = 12
NO_CELL_V = 0.5  # a cell input below this reads nothing wired
_STATUS = generated(LAYOUTS['EVMS3_Status'], Evms3Status)
BMS12_IDS = range(BMS12_BASE_ID, BMS12_BASE_ID + 10 * BMS12_MAX_MODULES)


@dataclass
class ZevaStatus:
    """An ID whose frames read as the ZEVA status, and what they said."""

    entry: IdTraffic
    readings: list[Evms3Status]

    @property
    def bms16(self) -> bool:
        """Tell whether every frame carries the BMS16 marker (byte 5 = 255)."""
        return all(r.bms16_marker for r in self.readings)

    @property
    def four_hz(self) -> bool:
        """Tell whether it comes at the 4 Hz of a ZEVA core."""
        return FOUR_HZ[0] <= self.entry.period_s <= FOUR_HZ[1]

    def describe(self) -> str:
        """Say what it showed."""
        last = self.readings[-1]
        return (f'status {self.entry.label()}: {self.entry.count} frames every '
                f'{self.entry.period_s * 1000:.0f} ms, state {last.state.name}, '
                f'{last.pack_voltage_v:g} V, {last.amp_hours_ah:g} Ah remaining')


def statuses(traffic: Traffic) -> list[ZevaStatus]:
    """
    Return every ID whose frames all read as the ZEVA status layout (DLC 8).

    The BMS12 IDs are left out: a core's IDs cannot overlap them (its codec refuses that),
    and a module's padded temperature frame can read as a status.
    """
    out = []
    for entry in traffic:
        if set(entry.dlcs) != {STATUS_LENGTH} or entry.can_id in BMS12_IDS \
                or sender_proven_elsewhere(entry):
            continue
        try:
            readings = [_STATUS(entry.can_id, data) for data in entry.payloads]
        except MalformedFrameError:
            continue
        if readings:
            out.append(ZevaStatus(entry, readings))
    return out


def module_cells(traffic: Traffic, module: int,
                 extended: bool) -> tuple[list[IdTraffic], int] | None:
    """
    Return the cell frames of one BMS12 module and how many cells it has (None: not heard).

    The count is the highest cell position that ever read a voltage: cells are wired from
    the first input on.
    """
    frames: list[IdTraffic] = []
    count = 0
    for t in (1, 2, 3):
        entry = traffic.get(BMS12_BASE_ID + 10 * module + t, extended)
        if entry is None:
            continue
        if set(entry.dlcs) != {8}:
            return None
        frames.append(entry)
        for data in entry.payloads:
            cells = decode_cells(data, module, 4 * (t - 1))
            for k, volts in enumerate(cells.voltages_v):
                if volts >= NO_CELL_V:
                    count = max(count, cells.first_cell + k + 1)
    return (frames, count) if frames else None


def modules(traffic: Traffic, extended: bool) -> dict[int, tuple[list[IdTraffic], int]]:
    """Return the BMS12 modules heard: module -> (its frames, its cell count)."""
    out = {}
    for module in range(BMS12_MAX_MODULES):
        found = module_cells(traffic, module, extended)
        if found is not None:
            out[module] = found
    return out


def module_extras(traffic: Traffic, module: int, extended: bool) -> list[IdTraffic]:
    """Return a module's request (t = 0, from the core) and temperature (t = 4) frames."""
    found = []
    for t in (0, 4):
        entry = traffic.get(BMS12_BASE_ID + 10 * module + t, extended)
        if entry is not None:
            found.append(entry)
    return found
