# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
SMA-family batteries (doc/protocols.md section 5): the SMA frames and their dialect.

The IDs are fixed: 0x351 limits, 0x355 SoC, 0x356 voltage/current/temperature (the primary
frame: one BatteryState each), 0x35A alarms, 0x35E manufacturer, 0x35F capacity. The
dialect is what else the battery sends: 0x359 / 0x35C (Pylontech and the BMSs copying it),
0x370..0x382 (Victron-compatible). The sma device decodes whichever it hears; the dialect
is evidence and a comment, not a setting. An inverter on the bus shows itself by its
keep-alive 0x305 (eight zero bytes).

The voltage scale of 0x356 (0.01 V as SMA writes it, 0.1 V from some senders) is decided by
a recogniser of its own, ``sma_voltage.py``, from ``facts['readings']`` (it refines this
candidate).
"""
from __future__ import annotations

from typing import Any

from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.probe.evidence import Candidate, stale_setting
from ams_can_bridge.probe.traffic import Key, Traffic
from ams_can_bridge.protocols.sma import (
    BATTERY_ID, INFO_ID, LIMITS_ID, MANUFACTURER_ID, SMA_IDS, SmaBattery, SmaCodec, SOC_ID)
from ams_can_bridge.protocols.sma_dialects import (
    DIALECT_IDS, PYLONTECH_ALARMS_ID, PYLONTECH_KEEPALIVE_ID, PYLONTECH_REQUEST_ID,
    VICTRON_PRODUCT_NAME_ID)
from ams_can_bridge.protocols.sma_scale import raw_voltage

DEFAULT_STALE_S = 5.0  # the device's 5 x 1 s
PYLONTECH_IDS = frozenset({PYLONTECH_ALARMS_ID, PYLONTECH_REQUEST_ID})
VICTRON_IDS = frozenset(i for i in DIALECT_IDS if 0x370 <= i <= VICTRON_PRODUCT_NAME_ID)
# What an inverter (or a Victron GX) sends on an SMA bus: 0x305 keep-alive, 0x306, 0x307
INVERTER_IDS = (PYLONTECH_KEEPALIVE_ID, 0x306, 0x307)
_WEIGHTS = {BATTERY_ID: 0.5, LIMITS_ID: 0.15, SOC_ID: 0.15, MANUFACTURER_ID: 0.1,
            INFO_ID: 0.05}


def recognise(traffic: Traffic, found: list[Candidate]) -> list[Candidate]:
    """Return the SMA-family battery, if its frames were heard."""
    codec = SmaCodec()
    readings: dict[int, Any] = {}
    unreadable: dict[int, str] = {}
    ids: set[Key] = set()
    for can_id in sorted(SMA_IDS | DIALECT_IDS):
        entry = traffic.get(can_id)
        if entry is None:
            continue
        try:
            readings[can_id] = [codec.decode(can_id, data) for data in entry.payloads][-1]
        except MalformedFrameError as exc:
            unreadable[can_id] = exc.reason
        ids.add(entry.key)
    if not readings.keys() & {BATTERY_ID, LIMITS_ID, SOC_ID}:
        return []
    score = sum(w for i, w in _WEIGHTS.items() if i in readings) + (
        0.1 if readings.keys() & ({0x35A} | PYLONTECH_IDS) else 0)
    dialect = _dialect(readings.keys() | unreadable.keys())
    cand = Candidate('sma', 'sma', f'SMA-family battery ({dialect})', min(score, 1.0),
                     frozenset(ids), [_described(traffic, readings)])
    cand.facts['readings'] = readings  # the last of each ID: for the voltage-scale decision
    cand.evidence.append(f'dialect {dialect}: ' + _dialect_evidence(readings, unreadable))
    for can_id, reason in unreadable.items():
        cand.notes.append(f'0x{can_id:03X}: {reason}: the bridge counts these malformed')
    if BATTERY_ID not in readings:
        cand.writable = False
        cand.notes.append('not written: no readable 0x356 (voltage, current, temperature): '
                          'the sma device publishes one BatteryState per 0x356')
    else:
        stale_setting(cand, traffic.get(BATTERY_ID).period_s,  # type: ignore[union-attr]
                      DEFAULT_STALE_S, '0x356 comes')
    _inverter(cand, traffic)
    return [cand]


def _dialect(heard: set[int]) -> str:
    kinds = [name for name, group in (('pylontech', PYLONTECH_IDS), ('victron', VICTRON_IDS))
             if heard & group]
    return ' + '.join(kinds) if kinds else 'sma'


def _dialect_evidence(readings: dict[int, Any], unreadable: dict[int, str]) -> str:
    heard = sorted(readings.keys() | unreadable.keys())
    extra = [i for i in heard if i in DIALECT_IDS]
    name = ''.join(getattr(readings.get(i), 'text', '') for i in (0x370, 0x371))
    product = getattr(readings.get(VICTRON_PRODUCT_NAME_ID), 'text', '')
    texts = [f'{what} {text!r}' for what, text in (('BMS name', name), ('product', product))
             if text]
    return ('beyond the SMA frames: ' + ', '.join(f'0x{i:03X}' for i in extra) if extra
            else 'only the SMA frames (0x35A alarms)') + ('; ' + ', '.join(texts) if texts else '')


def _described(traffic: Traffic, readings: dict[int, Any]) -> str:
    parts = []
    battery = readings.get(BATTERY_ID)
    if isinstance(battery, SmaBattery):
        entry = traffic.get(BATTERY_ID)
        assert entry is not None  # read above
        raw = raw_voltage(battery)  # as sent: its scale is decided afterwards (sma_voltage.py)
        volts = 'voltage not sent' if raw is None else f'voltage {raw} as sent'
        parts.append(f'0x356 every {entry.period_s:.3g} s: {volts}, {battery.current_a} A, '
                     f'{battery.temperature_c} degC')
    soc = readings.get(SOC_ID)
    if soc is not None:
        parts.append(f'SoC {soc.percent} %')
    maker = readings.get(MANUFACTURER_ID)
    if maker is not None:
        parts.append(f'manufacturer {maker.name!r}')
    return '; '.join(parts) or 'SMA frames'


def _inverter(cand: Candidate, traffic: Traffic) -> None:
    heard = [e for i in INVERTER_IDS if (e := traffic.get(i)) is not None and e.dlc == 8]
    keepalive = traffic.get(PYLONTECH_KEEPALIVE_ID)
    if keepalive is not None and keepalive.dlc == 8 and not any(
            any(data) for data in keepalive.payloads):
        cand.ids |= {e.key for e in heard}
        cand.evidence.append('an inverter is on this bus: ' + ', '.join(
            f'{e.label()} ({e.count})' for e in heard))
        cand.set('inverter_keepalive', False, 'an inverter sends the keep-alive 0x305 here: '
                 'a second sender of it must not join')
    elif PYLONTECH_IDS & {i for i, _ in cand.ids}:
        cand.set('inverter_keepalive', True, 'check: no inverter keep-alive (0x305) heard; a '
                 'Pylontech-style BMS may stop after 3 s without one: then true (sent only '
                 'while commands_enabled)', decided=False)
