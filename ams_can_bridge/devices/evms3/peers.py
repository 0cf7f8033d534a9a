# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What an EVMS3 device hears of its peers: the BMS12 modules and the TC chargers it drives.

Each BMS12 module's cells, temperatures and the balance target the EVMS asks of it (300 +
10 m, mV, 0 = off), and per TC charger 1..3 the EVMS's command and the charger's answer
(any set status bit is WARN). Every reading is kept with the ``Device.clock()`` it came at
and expires on its own: the owning ``Evms3Device`` passes its clock and its timeouts, and
calls these with its lock held (no locking here).
"""
from __future__ import annotations

from typing import Any

from ams_can_bridge.devices.timed import NAN, NEVER, TimedSpans, TimedStore
from ams_can_bridge.protocols.evms3 import Bms12Request, Bms12Temperatures
from ams_can_bridge.protocols.tc_charger import (
    CHARGERS, ChargerCommand, ChargerStatus, STATUS_BIT_TEXT)


class Bms12Module:
    """Last readings of one BMS12 module, each timed (Device.clock() of its frame)."""

    def __init__(self) -> None:
        self.cells = TimedSpans.uniform(4, 3)  # the frames t = 1..3, 4 cells each
        # Bms12Temperatures -> (t1, t2) (None: no sensor, raw 0); Bms12Request -> the balance
        # target the EVMS asks (None = balancing off)
        self.latest: TimedStore[type, Any] = TimedStore()

    def last_seen(self) -> float:
        return max(self.cells.newest(), self.latest.seen(Bms12Temperatures))

    def cell_voltages(self, count: int, now: float, timeout: float) -> list[float]:
        """Return the first count cells (V), NaN where unknown or older than timeout."""
        return self.cells.read(now, timeout, (count + 3) // 4)[:count]

    def temperatures(self, now: float, timeout: float) -> tuple[float | None, ...]:
        """Return (t1, t2) in degC: None = no sensor, NaN = unknown or older than timeout."""
        temps = self.latest.get(Bms12Temperatures, now, timeout)
        return (NAN, NAN) if temps is None else temps

    def values(self, m: int, count: int, now: float, timeout: float,
               values: dict[str, str]) -> None:
        """Add this module's diagnostic values, as module m of count cells."""
        cells = [v for v in self.cell_voltages(count, now, timeout) if v == v]
        temps = self.temperatures(now, timeout)
        seen = self.last_seen()
        values[f'module {m} cells'] = f'{len(cells)}/{count} received'
        if cells:
            values[f'module {m} cell min (V)'] = f'{min(cells):.3f}'
            values[f'module {m} cell max (V)'] = f'{max(cells):.3f}'
        values[f'module {m} temperatures (degC)'] = ', '.join(
            'no sensor' if t is None else 'unknown' if t != t else f'{t:g}' for t in temps)
        values[f'module {m} last heard'] = ('never' if seen == NEVER
                                            else f'{now - seen:.1f} s ago')
        values[f'module {m} balance target (mV)'] = self._balance_text(now, timeout)

    def _balance_text(self, now: float, timeout: float) -> str:
        if now - self.latest.seen(Bms12Request) > timeout:
            return 'unknown (no request from the EVMS)'
        balance_mv = self.latest.latest(Bms12Request)
        return 'off' if balance_mv is None else str(balance_mv)


class Chargers:
    """TC chargers 1..3: the EVMS's last command to each and the charger's last answer."""

    def __init__(self) -> None:
        self.commands: TimedStore[int, ChargerCommand] = TimedStore()
        self.status: TimedStore[int, ChargerStatus] = TimedStore()

    def offer(self, reading: ChargerCommand | ChargerStatus, now: float) -> None:
        """Keep a decoded charger frame, received at now."""
        if isinstance(reading, ChargerCommand):
            self.commands.put(reading.charger, reading, now)
        else:
            self.status.put(reading.charger, reading, now)

    def values(self, values: dict[str, str], now: float, timeout: float) -> list[str]:
        """Add each charger's values, named as ZEVA's Monitor names them; return the faults."""
        faults = []
        for n in range(1, CHARGERS + 1):
            command, command_seen = self.commands.latest(n), self.commands.seen(n)
            status, status_seen = self.status.latest(n), self.status.seen(n)
            if command is None and status is None:
                continue
            key = f'charger {n} '
            if command is not None and now - command_seen <= timeout:
                values[key + 'target volts (V)'] = f'{command.target_voltage_v:.1f}'
                values[key + 'target amps (A)'] = f'{command.current_limit_a:.1f}'
                values[key + 'shutdown by BMS'] = 'yes' if command.stop else 'no'
            if status is not None and now - status_seen <= timeout:
                values[key + 'output volts (V)'] = f'{status.output_voltage_v:.1f}'
                values[key + 'output amps (A)'] = f'{status.output_current_a:.1f}'
                values[key + 'status'] = ', '.join(status.active_bits) or 'OK'
                for bit, text in STATUS_BIT_TEXT.items():
                    values[key + text] = 'yes' if status.status & bit else 'no'
                values[key + 'temperature (raw)'] = ('not sent' if status.temperature_raw is None
                                                     else str(status.temperature_raw))
                if status.status:
                    faults.append(f'charger {n}: ' + ', '.join(status.active_bits))
            values[key + 'last heard'] = f'{now - max(command_seen, status_seen):.1f} s ago'
        return faults
