# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Values no battery reports are malformed frames: counted, never published (issue 26 point 7).

The attack frames carry what a red team sent (a BMS16 status of 3,738.9 V and 153 degC, a
BMS12 cell of 65.535 V, an AMS Temp_max of 255 degC) and the first value past each bound of
doc/protocols.md ("Physical bounds" and each protocol's ranges), every frame written by hand
from the byte tables there. Each goes through the engine as the bridge runs it: the frame is
counted as malformed with its reason, the device publishes nothing from it (a primary frame
no message at all, the rest of the frame unused), and the last good values stay.
The last test holds each range to msg_defs/*.dbc, so the DBCs and the code say the same.
"""
from __future__ import annotations

import math

import pytest

from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.core import Engine
from ams_can_bridge.offline.params_file import FileParams
from ams_can_bridge.protocols import ams, bms12, bms16, evms3, ivt_s, tc_charger
from ams_can_bridge.protocols.common import load_dbc
from helpers import Clock

X = True  # 29-bit


class Sink:
    """Each BatteryReport the engine emits, by device."""

    def __init__(self) -> None:
        self.reports: dict[str, list] = {}

    def battery(self, name, frame_id, report, arrays, stamp) -> None:
        self.reports.setdefault(name, []).append(report)

    def diagnostics(self, statuses, stamp) -> None:
        pass

    def clock(self, stamp) -> None:
        pass


# One device a rig: a standard-form BMS16 and an EVMS3 share the BMS12 IDs.
PARAMS = {'ams': {}, 'ivt': {'ivt.type': 'ivt_s'}, 'evms3': {'evms3.bms12_modules': 1},
          'bms16': {}, 'zeva16': {'zeva16.type': 'bms16', 'zeva16.variant': 'standard',
                                  'zeva16.base_id': 60}}


def rig(*names: str) -> tuple[Engine, Sink, DeviceSet]:
    values: dict = {}
    for name in names:
        values.update(PARAMS[name])
    params = FileParams(values)
    clock = Clock(1000.0)
    device_set = DeviceSet(list(names), params.declare, clock=clock)
    params.raise_errors()
    sink = Sink()
    status = BusStatus(state=BusState.CONNECTED, reason='', frames_in=0, frames_out=0,
                       frames_dropped_tx=0, error_frames=0, reconnects=0, hardware_id='x')
    engine = Engine(device_set, sink, status_prefix='bridge', interface='virtual',
                    bus_status=lambda: status, now=clock, monotonic=clock)
    return engine, sink, device_set


def send(engine: Engine, frame_id: int, hexdata: str, extended: bool = False) -> None:
    engine.on_frame(frame_id, bytes.fromhex(hexdata), extended, 1000.0)


# (device, primary frame that is good, attack frame, a text of its reason, extended ID)
# The primary frames: doc/protocols.md 1.1 (AMS 0x300), 4 (BMS16 500), 3.1 (EVMS3 30),
# 6 (standard BMS16 at base 60), 2.1 (IVT-S 0x521).
AMS_OK = 'C0 21 B4 23 42 01 00'          # IDLE, Volt_min 3.6 V, Temp_max 35, SOC 66 %
BMS16_OK = '00 50 10 02 10 80 19'        # SoC 80 %, 52.8 V, 1.6 A, 25 degC
EVMS3_OK = '02 04 D2 0D 80 83 63 41'     # Running, 123.4 Ah, 345.6 V, 13.1 V, 99 %, 25 degC
STD_OK = '02 04 D2 02 10 FF 00 41'       # Running, 123.4 Ah, 52.8 V, marker, 25 degC
IVT_OK = '00 00 FF FF D1 20'             # I = -12.0 A
ATTACKS = [
    # the red team's: BMS16 raw 37389 (0x920D LE) = 3,738.9 V and 153 degC (0x99)
    ('bms16', (500, BMS16_OK), (500, '00 50 0D 92 10 80 99'), '3738.9 V', False),
    # the document's ranges: 80.1 V; -1000.1 A (raw 22767 = 0x58EF); 121 degC
    ('bms16', (500, BMS16_OK), (500, '00 50 21 03 10 80 19'), '80.1 V', False),
    ('bms16', (500, BMS16_OK), (500, '00 50 10 02 EF 58 19'), '-1000.1 A', False),
    ('bms16', (500, BMS16_OK), (500, '00 50 10 02 10 80 79'), '121 degC', False),
    # cell 3 of 501 = 0xF5 + 256 (9th bit in byte 6 bit 2) = 5.01 V, above the 5.00 V
    ('bms16', (500, BMS16_OK), (501, '4A 4A F5 4A 4A 4A 04'), 'cell 3 5.01 V', False),
    # the red team's AMS Temp_max 255 degC; 201 degC is past the bound as well
    ('ams', (0x300, AMS_OK), (0x300, 'C0 21 B4 FF 42 02 00'), 'Temp_max 255 degC', False),
    ('ams', (0x300, AMS_OK), (0x300, 'C0 21 B4 C9 42 02 00'), 'Temp_max 201 degC', False),
    # the red team's BMS12 cell of 65.535 V (0xFFFF mV); 10.001 V (0x2711) is past 10 V
    ('evms3', (30, EVMS3_OK), (301, '0C E5 0C E6 0D 05 FF FF'), '65.535 V', X),
    ('evms3', (30, EVMS3_OK), (301, '27 11 0C E6 0D 05 0C E5'), '10.001 V', X),
    # BMS12 temperature 241 - 40 = 201 degC; EVMS3 temperature byte 7 = 241
    ('evms3', (30, EVMS3_OK), (304, '41 F1 00 00 00 00 00 00'), '201 degC', X),
    ('evms3', (30, EVMS3_OK), (30, '02 04 D2 0D 80 83 63 F1'), '201 degC', X),
    # standard BMS16: 160.1 V (0x0641) is more than 16 cells of 10 V; its cells are BMS12's
    ('zeva16', (60, STD_OK), (60, '02 04 D2 06 41 FF 00 41'), '160.1 V', X),
    ('zeva16', (60, STD_OK), (301, '0C E5 0C E6 0D 05 FF FF'), '65.535 V', X),
    # IVT-S temperature 200.1 degC (raw 2001 = 0x7D1) and -273.2 degC (raw -2732)
    ('ivt', (0x521, IVT_OK), (0x525, '04 00 00 00 07 D1'), '200.1 degC', False),
    ('ivt', (0x521, IVT_OK), (0x525, '04 00 FF FF F5 54'), '-273.2 degC', False),
]


@pytest.mark.parametrize('name, good, attack, reason, extended', ATTACKS,
                         ids=[f'{a[0]}-{a[3]}' for a in ATTACKS])
def test_impossible_values_are_malformed_never_published(name, good, attack, reason, extended):
    engine, sink, device_set = rig(name)
    device = device_set.devices[name]
    send(engine, *good, extended)
    before = sink.reports[name][-1]
    assert before.present
    send(engine, *attack, extended)
    assert device.frames_malformed == 1
    assert reason in device.last_malformed, device.last_malformed
    if attack[0] == good[0]:  # a primary frame: no message at all from it
        assert len(sink.reports[name]) == 1
    send(engine, *good, extended)  # nothing of the attack frame in the next message
    after = sink.reports[name][-1]
    for field in ('voltage', 'current', 'temperature', 'percentage'):
        assert same(getattr(after, field), getattr(before, field)), field
    assert all(math.isnan(v) or 0 <= v <= 10 for v in after.cell_voltage)
    assert all(math.isnan(v) or v <= 200 for v in after.cell_temperature)
    report = device.diagnostic_report()
    assert report.values['frames malformed'] == '1'


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def test_the_last_good_values_at_each_bound_are_published():
    """The bounds themselves are values: 200 degC, 10 V, 80 V, 5.00 V pass."""
    engine, sink, device_set = rig('ams', 'ivt', 'evms3', 'bms16')
    send(engine, 0x300, 'C0 21 B4 C8 42 01 00')  # Temp_max 200 degC
    assert sink.reports['ams'][-1].present and device_set.devices['ams'].frames_malformed == 0
    send(engine, 500, '00 50 20 03 F0 58 78')  # 80.0 V, -1000.0 A, 120 degC
    assert sink.reports['bms16'][-1].voltage == 80.0
    assert sink.reports['bms16'][-1].temperature == 120.0
    send(engine, 501, '4A 4A F4 4A 4A 4A 04')  # cell 3 = 5.00 V
    send(engine, 500, BMS16_OK)
    assert sink.reports['bms16'][-1].cell_voltage[2] == 5.0
    send(engine, 301, '27 10 0C E6 0D 05 0C E5', X)  # cell 1 = 10.000 V
    send(engine, 30, EVMS3_OK, X)
    assert sink.reports['evms3'][-1].cell_voltage[0] == 10.0
    send(engine, 0x525, '04 00 00 00 07 D0')  # IVT-S T = 200.0 degC
    assert device_set.devices['ivt'].frames_malformed == 0
    assert all(d.frames_malformed == 0 for d in device_set.devices.values())


# --- every checked range is its DBC's ------------------------------------------------------
def _checked_rows():
    """(DBC, message name, row) of every row whose check refuses a value outside its range."""
    tables = [('ams', layout) for layout in ams.LAYOUTS.values()]
    tables += [('bms16', layout) for layout in bms16.LAYOUTS]
    zeva = (*evms3.LAYOUTS.values(), *bms12.LAYOUTS.values(), *tc_charger.LAYOUTS.values())
    tables += [('evms3', layout) for layout in zeva]
    tables += [('ivt_s', layout) for layout in ivt_s.LAYOUTS.values()]
    for dbc, layout in tables:
        for row in layout.signals:
            if row.check and row.lookup is None:
                yield dbc, layout.name, row


def _physical(row, raw: int | None) -> float | None:
    return None if raw is None else raw * row.scale + row.offset


@pytest.mark.parametrize('dbc, message, row', list(_checked_rows()),
                         ids=lambda v: v if isinstance(v, str) else v.name)
def test_every_checked_range_is_the_dbc_range(dbc, message, row):
    signal = load_dbc(dbc).get_message_by_name(message).get_signal_by_name(row.name)
    low, high = row.bounds()
    # a DBC range may also hold the raw "not available" marker (EVMS3 isolation 101)
    marker = _physical(row, row.invalid)
    assert signal.minimum in (pytest.approx(low), marker), (signal.minimum, low)
    assert signal.maximum in (pytest.approx(high), marker), (signal.maximum, high)


def test_the_physical_bounds_are_in_the_tables():
    """The rows the bounds were added to (a table edit dropping one fails here first)."""
    names = {(m, row.name): row.bounds() for _, m, row in _checked_rows()}
    assert names[('AMS_Status', 'Temp_max')] == (0, 200)
    assert names[('BMS16_Status', 'Voltage')] == (0, 80)
    assert names[('BMS16_Status', 'Current')] == (-1000, 1000)
    assert names[('BMS16_Status', 'Temperature')] == (0, 120)
    assert names[('EVMS3_Status', 'Temperature')][1] == 200
    assert names[('BMS12_M0_Cells1to4', 'Cell1')] == (0, 10)
    assert names[('BMS12_M0_Temperatures', 'Temperature1')][1] == 200
    assert names[('IVT_Msg_Result_T', 'IVT_Result_T')] == (-273.15, 200)
