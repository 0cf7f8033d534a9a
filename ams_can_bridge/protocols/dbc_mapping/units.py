# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
DBC units as real files spell them, and what each is to BatteryState.

CANdb++ users write ``V``, ``mV``, ``%``, ``degC``; the Orion BMS utility exports ``Volts``,
``Amps``, ``Amphours``, ``Percent``, ``Celsius``; Volkswagen's DBCs ``Unit_Volt``,
``Unit_DegreCelsi``, ``Unit_PerCent``. A unit is read case-insensitively, without spaces,
hyphens and a leading ``Unit_``, so ``Amp-hours``, ``amp hours`` and ``AmpHours`` are one.
Each known unit belongs to a quantity and converts to its base unit (the one BatteryState
uses): ``wanted = value * factor + add``. Power, energy, resistance and time units are known
only to say "this is not a voltage". doc/protocols.md section 8 lists them.
"""
from __future__ import annotations

from dataclasses import dataclass

# BatteryState's quantities: their base units as the start log and doc/own_bms.md write them
BASE = {'V': 'V', 'A': 'A', 'Ah': 'Ah', 'fraction': '0..1', 'degC': 'degC'}
QUANTITY_NAMES = {'V': 'a voltage', 'A': 'a current', 'Ah': 'a charge', 'fraction': 'a ratio',
                  'degC': 'a temperature', 'W': 'a power', 'Wh': 'an energy',
                  'Ohm': 'a resistance', 's': 'a time'}
KELVIN = -273.15
_F = 5 / 9, -160 / 9  # degF -> degC


@dataclass(frozen=True)
class Unit:
    """A DBC unit: its quantity and how it becomes the quantity's base unit."""

    quantity: str  # a key of QUANTITY_NAMES
    factor: float = 1.0
    add: float = 0.0


def _table() -> dict[str, Unit]:
    spelled: dict[str, tuple[str, float, float, tuple[str, ...]]] = {
        # quantity, factor, add, spellings (normalised: lower case, no spaces or hyphens)
        'V': ('V', 1.0, 0.0, ('v', 'volt', 'volts', 'vdc')),
        'mV': ('V', 1e-3, 0.0, ('mv', 'millivolt', 'millivolts')),
        'kV': ('V', 1e3, 0.0, ('kv', 'kilovolt', 'kilovolts')),
        'uV': ('V', 1e-6, 0.0, ('uv', 'µv', 'μv', 'microvolt', 'microvolts')),
        'dV': ('V', 0.1, 0.0, ('dv',)),
        'cV': ('V', 0.01, 0.0, ('cv',)),
        'A': ('A', 1.0, 0.0, ('a', 'amp', 'amps', 'ampere', 'amperes', 'amper')),
        'mA': ('A', 1e-3, 0.0, ('ma', 'milliamp', 'milliamps', 'milliampere',
                                'milliamperes')),
        'kA': ('A', 1e3, 0.0, ('ka', 'kiloamp', 'kiloamps')),
        'uA': ('A', 1e-6, 0.0, ('ua', 'µa', 'μa', 'microamp', 'microamps')),
        'dA': ('A', 0.1, 0.0, ('da',)),
        'cA': ('A', 0.01, 0.0, ('ca',)),
        'Ah': ('Ah', 1.0, 0.0, ('ah', 'ahr', 'ahrs', 'amphour', 'amphours', 'amperehour',
                                'amperehours', 'amperhour')),
        'mAh': ('Ah', 1e-3, 0.0, ('mah', 'milliamphour', 'milliamphours')),
        'kAh': ('Ah', 1e3, 0.0, ('kah',)),
        'As': ('Ah', 1 / 3600, 0.0, ('as', 'amperesecond', 'ampereseconds', 'coulomb',
                                     'coulombs')),
        'mAs': ('Ah', 1 / 3.6e6, 0.0, ('mas',)),
        '%': ('fraction', 0.01, 0.0, ('%', 'percent', 'percents', 'pct', 'percentage')),
        '‰': ('fraction', 0.001, 0.0, ('‰', 'permille', 'promille', '01%')),  # '0.1 %'
        '0.01%': ('fraction', 1e-4, 0.0, ('001%', '‱', 'permyriad', 'basispoint')),
        '0..1': ('fraction', 1.0, 0.0, ('01', 'ratio', 'fraction')),  # '0..1'
        'degC': ('degC', 1.0, 0.0, ('degc', '°c', 'c', 'degreec', 'degreesc', 'celsius',
                                    'degcelsius', 'degreecelsius', 'degreescelsius', '℃',
                                    'degrecelsi')),
        'K': ('degC', 1.0, KELVIN, ('k', 'kelvin', 'kelvins')),
        'dK': ('degC', 0.1, KELVIN, ('dk',)),
        'degF': ('degC', _F[0], _F[1], ('degf', '°f', 'degreef', 'degreesf', 'fahrenheit',
                                        '℉')),
        'W': ('W', 1.0, 0.0, ('w', 'watt', 'watts')),
        'kW': ('W', 1e3, 0.0, ('kw', 'kilowatt', 'kilowatts')),
        'Wh': ('Wh', 1.0, 0.0, ('wh', 'watthour', 'watthours')),
        'kWh': ('Wh', 1e3, 0.0, ('kwh', 'kilowatthour', 'kilowatthours')),
        'Ohm': ('Ohm', 1.0, 0.0, ('ohm', 'ohms', 'ω')),
        'mOhm': ('Ohm', 1e-3, 0.0, ('mohm', 'mohms', 'mω', 'milliohm', 'milliohms')),
        'kOhm': ('Ohm', 1e3, 0.0, ('kohm', 'kohms', 'kω', 'kiloohm', 'kiloohms')),
        's': ('s', 1.0, 0.0, ('s', 'sec', 'second', 'seconds', 'secon')),
        'ms': ('s', 1e-3, 0.0, ('ms', 'millisecond', 'milliseconds', 'millisecon')),
    }
    return {spelling: Unit(quantity, factor, add)
            for quantity, factor, add, spellings in spelled.values() for spelling in spellings}


UNITS = _table()


def unit_text(unit: str) -> str:
    """
    Return a DBC unit as its author wrote it.

    cantools reads DBC files as cp1252 (the usual encoding of CANdb++ files), so a UTF-8
    file's '°C' arrives as 'Â°C'; both mean degC.
    """
    text = unit.strip()
    try:
        return text.encode('cp1252').decode('utf-8')
    except UnicodeError:
        return text


def normalise(unit: str) -> str:
    """Return the key a unit is known by: lower case, no blanks, hyphens or 'Unit_'."""
    text = unit_text(unit)
    if text[:5].lower() == 'unit_':  # Volkswagen: Unit_Volt, Unit_DegreCelsi
        text = text[5:]
    text = text.replace('deg ', 'deg').replace('degree ', 'degree')
    return ''.join(ch for ch in text.lower() if ch not in ' -_.')


def lookup(unit: str) -> Unit | None:
    """Return what a DBC unit is (None: not a unit this package knows)."""
    return UNITS.get(normalise(unit)) if unit.strip() else None
