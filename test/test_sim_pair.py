# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""simulator --pack: two batteries on one bus, read by config/pack.yaml's pack, no ROS."""
from __future__ import annotations

from pathlib import Path
import threading
import time
import uuid

import can
import pytest

from ams_can_bridge.devices.base import Level
from ams_can_bridge.devices.pack.limits import Severity
from ams_can_bridge.offline.params_file import load_parameters
from ams_can_bridge.sim.main import main as simulator_main
from ams_can_bridge.sim.pair import (
    build_pair, CELL_OVER_SECONDS, PairScenario, parse_scenario, SILENCE_SECONDS)
from helpers import Clock
from pack_rig import build

PACK_YAML = Path(__file__).resolve().parents[1] / 'config' / 'pack.yaml'
STEP = 0.01  # s between simulated ticks


def pack_params() -> dict:
    """config/pack.yaml's bridge parameters, checked by the bridge's own declarations."""
    values = load_parameters(str(PACK_YAML), 'ams_can_bridge')
    return {k: v for k, v in values.items() if not k.startswith('can.')}  # the bus is ours


class Stepped:
    """The pair (with its scenarios) ticked on simulated time into the pack's engine."""

    def __init__(self, *scenarios: str) -> None:
        self.clock = Clock(0.0)
        self.engine, self.sink, device_set = build(pack_params(), self.clock)
        self.pack = device_set.devices['pack']
        self.sims = build_pair()
        self.sims.insert(0, PairScenario(self.sims, [parse_scenario(s) for s in scenarios]))
        self.t = 0.0

    def run_until(self, end: float) -> None:
        while self.t < end - 1e-9:
            self.clock.now = self.t
            for sim in self.sims:
                for f in sim.tick(self.t):
                    self.engine.on_frame(f.arbitration_id, f.data, f.is_extended_id, self.t)
            self.t = round(self.t + STEP, 6)

    def status(self) -> tuple[Level, str]:
        report = self.pack.diagnostic_report()
        return report.level, report.message

    def last(self, name: str):
        return self.sink.reports[name][-1][0]

    def figures(self) -> dict:
        return self.sink.figure_msgs['pack'][-1][0]


def test_drift_shows_as_the_packs_parallel_voltage_mismatch_naming_both():
    pair = Stepped('drift@1')
    pair.run_until(1.0)
    assert pair.status() == (Level.OK, 'OK')
    start_gap = pair.last('bms16').voltage - pair.last('evms3').voltage
    assert abs(start_gap) < 1.0  # the pair starts in step: 16 LiFePO4 beside 13 NMC cells
    pair.run_until(12.0)
    bms16, evms3 = pair.last('bms16').voltage, pair.last('evms3').voltage
    assert bms16 - evms3 > 1.5  # the EVMS3 fell away: 2 Ah/s for 10 s of 100 Ah
    level, message = pair.status()
    assert level == Level.WARN
    assert message == (f'bms16 {bms16:.3f} V and evms3 {evms3:.3f} V differ by more than '
                       '1.5 V')


def test_silence_names_the_stale_member_zeroes_the_limits_and_it_comes_back():
    pair = Stepped('silence@1')
    pair.run_until(1.0)
    assert pair.figures()['charge_current_limit'] == 40.0
    pair.run_until(1.0 + SILENCE_SECONDS - 0.5)  # silent for longer than stale_timeout 1.25 s
    assert pair.status() == (Level.WARN, 'evms3 is stale')
    assert pair.figures()['charge_current_limit'] == 0.0
    assert pair.figures()['discharge_current_limit'] == 0.0
    assert pair.last('pack').present
    pair.run_until(1.0 + SILENCE_SECONDS + 1.0)
    assert pair.status() == (Level.OK, 'OK')
    assert pair.figures()['charge_current_limit'] == 40.0
    assert pair.figures()['discharge_current_limit'] == 150.0


def test_cell_over_raises_the_msl_after_the_debounce_and_it_stays_latched():
    pair = Stepped('cell_over@1')
    over_since = None
    while pair.t < 1.0 + CELL_OVER_SECONDS:
        pair.run_until(pair.t + STEP)
        reports = pair.sink.reports.get('evms3', [])
        if over_since is None and reports and reports[-1][0].cell_voltage[0] > 4.20:
            over_since = pair.t - STEP  # the report that first carried the cell past MSL
        level, message = pair.status()
        if over_since is None or pair.t - STEP - over_since < 0.5 - 1e-6:
            assert level != Level.ERROR, (pair.t, message)  # not before the debounce
    assert over_since is not None
    level, message = pair.status()
    assert level == Level.ERROR and 'MSL cell_voltage_max: beyond 4.2 V' in message
    event = pair.pack.pack.limits.events[('cell_voltage_max', Severity.MSL)]
    assert 0.5 <= event.raised_at - over_since <= 0.5 + 0.5 + 1e-6  # one 0.5 s cell period
    assert event.worst > 4.2
    pair.run_until(1.0 + CELL_OVER_SECONDS + 2.0)  # the cell is back inside: still latched
    assert max(pair.last('evms3').cell_voltage) < 4.15
    level, message = pair.status()
    assert level == Level.ERROR and message.startswith('MSL cell_voltage_max')
    assert pair.figures()['charge_current_limit'] == 0.0
    assert pair.pack.clear_events() == (True, 'pack: cleared: cell_voltage_max')
    pair.run_until(pair.t + 0.5)
    assert pair.status() == (Level.OK, 'OK')
    assert pair.figures()['charge_current_limit'] == 40.0


def test_simulator_pack_on_a_virtual_bus_plays_all_three_into_the_pack():
    """The simulator's own main() on a python-can virtual bus; the pack decodes what it hears."""
    channel = f'test_pair_{uuid.uuid4().hex[:8]}'
    reader = can.Bus(interface='virtual', channel=channel)
    clock = Clock(time.monotonic())
    engine, _, device_set = build(pack_params(), clock)
    pack = device_set.devices['pack']
    args = ['--interface', 'virtual', '--channel', channel, '--pack', '--quiet',
            '--scenario', 'silence@0.5', '--scenario', 'cell_over@6',
            '--scenario', 'drift@4', '--duration', '13']
    result: list[int] = []
    sim = threading.Thread(target=lambda: result.append(simulator_main(args)), daemon=True)
    seen: list[str] = []
    try:
        sim.start()
        deadline = time.monotonic() + 40.0  # the machine is loaded: generous
        while sim.is_alive() and time.monotonic() < deadline:
            msg = reader.recv(timeout=0.1)
            clock.now = time.monotonic()
            if msg is not None:
                engine.on_frame(msg.arbitration_id, bytes(msg.data), msg.is_extended_id,
                                clock.now)
            text = pack.diagnostic_report().message
            if not seen or seen[-1] != text:
                seen.append(text)
        sim.join(timeout=5.0)
    finally:
        reader.shutdown()
    assert result == [0]
    assert 'evms3 is stale' in seen
    assert 'OK' in seen[seen.index('evms3 is stale'):]  # and it came back
    final = pack.diagnostic_report()
    assert final.level == Level.ERROR  # latched though the cell came back at 9 s
    assert 'MSL cell_voltage_max: beyond 4.2 V' in final.message
    assert any('bms16' in t and 'evms3' in t and 'differ by more than 1.5 V' in t
               for t in seen)


def test_scenarios_need_the_pair_and_say_how(capsys):
    assert simulator_main(['--scenario', 'drift', '--duration', '0']) == 2
    assert '--scenario plays on the pair of config/pack.yaml: add --pack' in (
        capsys.readouterr().err)
    with pytest.raises(ValueError, match='use one of drift, silence, cell_over'):
        parse_scenario('flood')
    with pytest.raises(ValueError, match='START must be seconds'):
        parse_scenario('drift@soon')


def test_the_members_in_parallel_carry_the_same_current_at_the_same_moment():
    # The BMS16's own time base is the clock's; the EVMS3's, the time since its first tick.
    # On a clock far from 0 (a live run's monotonic time) they must still agree.
    bms16, evms3 = build_pair()
    seen = []
    for step in range(400):
        now = 5000.0 + step * STEP * 5
        bms16.tick(now)
        evms3.tick(now)
        seen.append((round(bms16.current_a, 6), round(evms3.current_a, 6)))
    assert len(set(seen)) > 20  # the drive profile moves
    assert [b for b, _ in seen] == [e for _, e in seen]
