# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``pack`` section probe suggests when it hears more than one battery: commented out.

Whether several batteries form one battery, and how they are wired, is not on the bus: probe
writes the section (doc/packs.md) commented out, each setting under what to check. It guesses
the connection from the voltages the bridge's own devices read from the frames heard
(``readings``): parallel members share one voltage (Battery-Emulator joins a second pack only
within 1.5 V, the pack WARNs beyond ``max_voltage_difference``), so members further apart are
in series or no pack at all; equal members in series read alike too, so "parallel" stays a
guess. The limits tables are a typical table of the cell chemistry the cell voltages suggest.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

from ams_can_bridge.devices.pack.device import NOT_BATTERIES
from ams_can_bridge.errors import ConfigError
from ams_can_bridge.probe.evidence import Candidate, Setting
from ams_can_bridge.probe.traffic import Traffic

MAX_VOLTAGE_DIFFERENCE = 1.5  # V: the pack's default max_voltage_difference
LFP_CELL_MAX = 3.65  # V: a LiFePO4 cell full; a cell read above it is no LiFePO4 cell
# [MOL, RSL, MSL] tables by chemistry: typical values, the datasheet's win
CELL_LIMITS = {
    'LiFePO4': {'cell_voltage_max': [3.55, 3.6, 3.65], 'cell_voltage_min': [2.9, 2.7, 2.5]},
    'Li-ion (NMC)': {'cell_voltage_max': [4.15, 4.2, 4.25],
                     'cell_voltage_min': [3.0, 2.8, 2.5]},
}
# charging below 0 degC plates lithium; above ~55 degC cells age fast (both chemistries)
TEMPERATURE_LIMITS = {'temperature_max': [45.0, 50.0, 55.0],
                      'temperature_min': [5.0, 0.0, -10.0]}


@dataclass
class Reading:
    """What the bridge's device read from the frames heard: the last voltage, the cells."""

    voltage: float = math.nan
    cells: list[float] = field(default_factory=list)  # the known cell voltages


@dataclass
class PackSuggestion:
    """The commented section: what to check, the devices line with the pack, its settings."""

    name: str
    check: str
    devices: list[str]
    settings: list[Setting]


def batteries(written: list[Candidate]) -> list[Candidate]:
    """Return the written devices that report a battery (what a pack may combine)."""
    return [c for c in written if c.type not in NOT_BATTERIES]


def readings(traffic: Traffic, written: list[Candidate]) -> dict[str, Reading]:
    """
    Replay the sampled frames through the devices as the params file sets them.

    The same devices the bridge builds from the file (the decided settings), fed the first
    payloads probe kept of each ID in time order: each battery's last present voltage and
    cells. Empty when the devices cannot be built (the file's own check then says why).
    """
    from ams_can_bridge.offline.converter import Converter  # the bridge's device set
    values: dict[str, object] = {'devices': [c.name for c in written]}
    for cand in written:
        values[f'{cand.name}.type'] = cand.type
        values.update({f'{cand.name}.{s.key}': s.value for s in cand.settings if s.decided})
    try:
        converter = Converter(values, None, 'probe')
    except ConfigError:
        return {}
    claimed = set().union(*(c.ids for c in written)) if written else set()
    frames = sorted((stamp, entry.can_id, entry.extended, data) for entry in traffic
                    if entry.key in claimed for stamp, data in entry.samples)
    wanted = {c.name for c in batteries(written)}
    found: dict[str, Reading] = {}
    for stamp, can_id, extended, data in frames:
        converter.now = stamp
        for device in converter.devices.handle_frame(can_id, data, extended, stamp):
            if device.name not in wanted:
                continue
            report = device.battery_report()
            if report.present and math.isfinite(report.voltage):
                found[device.name] = Reading(report.voltage, [
                    v for v in report.cell_voltage if math.isfinite(v)])
    return found


def _connection(members: list[str], found: dict[str, Reading]) -> tuple[str, str]:
    """Guess parallel or series from the members' voltages; say why, and what to check."""
    unknown = [m for m in members if m not in found]
    if unknown:
        return 'parallel', (f'check: probe read no voltage of {", ".join(unknown)}: '
                            'parallel (one voltage, currents summed) or series (voltages '
                            'summed): how are they wired?')
    volts = [found[m].voltage for m in members]
    heard = ', '.join(f'{m} {v:.1f} V' for m, v in zip(members, volts))
    if max(volts) - min(volts) <= MAX_VOLTAGE_DIFFERENCE:
        return 'parallel', (f'check: {heard}: within {MAX_VOLTAGE_DIFFERENCE:g} V, as '
                            'parallel members must be; equal members in series read alike '
                            'too: check the wiring')
    return 'series', (f'check: {heard}: more than {MAX_VOLTAGE_DIFFERENCE:g} V apart, so not '
                      'in parallel (the pack would WARN); in series the pack reads their sum '
                      f'({sum(volts):.1f} V); if they are separate batteries, leave the pack '
                      'out')


def _limits(members: list[str], found: dict[str, Reading]) -> list[Setting]:
    """Return the limits tables: a typical one for the chemistry the cells suggest."""
    cells = [v for m in members if m in found for v in found[m].cells]
    out = []
    if cells:
        low, high = min(cells), max(cells)
        chemistry = 'Li-ion (NMC)' if high > LFP_CELL_MAX else 'LiFePO4'
        why = (f'check: [MOL, RSL, MSL] V; the cells read {low:.3f}..{high:.3f} V, like '
               f'{chemistry} cells: a typical {chemistry} table, take yours from the cell '
               'datasheet')
        for key, levels in CELL_LIMITS[chemistry].items():
            out.append(Setting(f'limits.{key}', levels, why, False))
            why = ''
    why = ('check: [MOL, RSL, MSL] degC, typical for lithium cells (no charging below '
           '0 degC): take yours from the datasheet'
           + ('' if cells else '; no cell voltage heard: add cell_voltage_max and '
              'cell_voltage_min the same way'))
    for key, levels in TEMPERATURE_LIMITS.items():
        out.append(Setting(f'limits.{key}', levels, why, False))
        why = ''
    return out


def suggest(written: list[Candidate], found: dict[str, Reading]) -> PackSuggestion | None:
    """Return the commented pack section for more than one battery, else None."""
    members = [c.name for c in batteries(written)]
    if len(members) < 2:
        return None
    used = {c.name for c in written}
    name, n = 'pack', 1
    while name in used:
        n += 1
        name = f'pack_{n}'
    connection, why = _connection(members, found)
    current = ('check: A the pack may {} inside MOL (datasheet); 0 leaves {}_current_limit '
               'NaN')
    settings = [
        Setting('type', 'pack', '', False),
        Setting('members', members, 'check: the batteries that form one battery, as probe '
                'named them above; remove any that is a battery of its own', False),
        Setting('connection', connection, why, False),
        Setting('max_charge_current', 0.0, current.format('be charged with', 'charge'),
                False),
        Setting('max_discharge_current', 0.0, current.format('deliver', 'discharge'), False),
        *_limits(members, found),
    ]
    check = (f'check: probe heard {len(members)} batteries ({", ".join(members)}). To read '
             f'them as one battery ({name}/battery_state, current limits, time to go and '
             'safety events: doc/packs.md), use this devices line instead of the one above '
             'and uncomment the section below it, each setting checked first')
    return PackSuggestion(name, check, [c.name for c in written] + [name],
                          [Setting(f'{name}.{s.key}', s.value, s.why, False)
                           for s in settings])
