# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""AMS simulator: state machine, heartbeat watchdog, relays, physics, periods, faults."""
import math
import pytest

from ams_can_bridge import registry
from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.devices.base import Level
from ams_can_bridge.protocols.ams import (
    AmsChargerStatus, AmsCodec, AmsError, AmsErrorEvent, AmsState, AmsStatus, CarCommand,
    CarStatus, CellVoltages, ChargerCommand, ChargerStart, OverrideBankCount,
    OverrideChargeCurrent)
from ams_can_bridge.errors import MalformedFrameError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.sim.ams import AmsSimulator

TICK = 0.002  # the SimRunner's default tick period
HEARTBEAT = 0.05


class Bench:
    """Drive a simulator in simulated time, acting as the car master (heartbeat)."""

    def __init__(self, sim=None, base_id=0x300, banks=1):
        self.sim = sim or AmsSimulator(base_id=base_id, bank_count=banks)
        self.codec = AmsCodec(base_id)
        self.banks = banks
        self.now = 0.0
        self.counter = 0
        self.next_beat = 0.0
        self.frames = []  # (time, Frame)

    def send(self, message):
        self.sim.on_frame(self.codec.encode(message), self.now)

    def run(self, seconds, command=CarCommand.NO_COMMAND, heartbeat=True, banks=None):
        end = self.now + seconds
        while self.now < end - 1e-9:
            if heartbeat and self.now >= self.next_beat - 1e-9:
                self.send(CarStatus(command, banks or self.banks, self.counter))
                self.counter = (self.counter + 1) & 0xFF
                self.next_beat += HEARTBEAT
            self.frames += [(self.now, f) for f in self.sim.tick(self.now)]
            self.now += TICK
            if not heartbeat:
                self.next_beat = self.now

    def decoded(self, kind, since=0.0):
        out = []
        for t, frame in self.frames:
            if t >= since:
                reading = self.codec.decode(frame.arbitration_id, frame.data)
                if isinstance(reading, kind):
                    out.append(reading)
        return out

    def last_status(self):
        return self.decoded(AmsStatus)[-1]


def relays(status):
    word = status.status
    return word.air_plus, word.air_minus, word.precharge


def test_registry():
    assert registry.load(registry.SIMULATORS['ams']) is AmsSimulator
    assert AmsSimulator.TYPE == 'ams'


def test_starts_idle_with_open_relays():
    bench = Bench()
    bench.run(0.3)
    status = bench.last_status()
    assert status.status.state is AmsState.IDLE and bench.sim.state is AmsState.IDLE
    assert relays(status) == (False, False, False)
    assert status.status.bank_count == 1 and status.soc_pct == 80
    assert bench.sim.pack_current_a(bench.now) == 0.0


def test_car_sequence_to_drive_and_abort():
    bench = Bench()
    bench.run(0.2, CarCommand.ENABLE_SC)
    assert bench.last_status().status.state is AmsState.SC_ENABLED
    assert relays(bench.last_status()) == (False, False, False)
    bench.run(0.2, CarCommand.ENABLE_TS)
    status = bench.last_status()
    assert status.status.state is AmsState.PRECHARGING
    assert relays(status) == (False, True, True)  # AIR- and precharge closed
    bench.run(0.25)  # precharge_time 0.5 s after entering PRECHARGING
    assert bench.last_status().status.state is AmsState.PRECHARGING
    bench.run(0.1)
    status = bench.last_status()
    assert status.status.state is AmsState.TS_ACTIVE
    assert relays(status) == (True, True, False)
    assert bench.sim.pack_current_a(bench.now) == 0.0  # no current allowed in TS_ACTIVE
    bench.run(0.1, CarCommand.ENABLE_DRIVE)
    assert bench.last_status().status.state is AmsState.DRIVE
    assert bench.sim.pack_current_a(bench.now) != 0.0
    bench.run(0.1, CarCommand.ABORT)
    status = bench.last_status()
    assert status.status.state is AmsState.IDLE and relays(status) == (False, False, False)


def test_state_change_sends_a_status_at_once():
    bench = Bench()
    bench.run(0.55)
    before = len(bench.decoded(AmsStatus))
    bench.run(0.01)  # between two 100 ms slots: no periodic status
    assert len(bench.decoded(AmsStatus)) == before
    bench.send(CarStatus(CarCommand.ENABLE_SC, 1, 0))
    bench.frames += [(bench.now, f) for f in bench.sim.tick(bench.now)]
    assert len(bench.decoded(AmsStatus)) == before + 1
    assert bench.last_status().status.state is AmsState.SC_ENABLED


@pytest.mark.parametrize('command', [CarCommand.ENABLE_TS, CarCommand.ENABLE_DRIVE,
                                     CarCommand.SET_BANK_COUNT, CarCommand.SYNC_TIME])
def test_commands_out_of_order_are_ignored(command):
    bench = Bench()
    bench.run(0.3, command)
    assert bench.last_status().status.state is AmsState.IDLE


def test_enable_drive_needs_ts_active():
    bench = Bench()
    bench.run(0.1, CarCommand.ENABLE_SC)
    bench.run(0.2, CarCommand.ENABLE_DRIVE)
    assert bench.sim.state is AmsState.SC_ENABLED


def test_heartbeat_loss_opens_relays_and_returns_to_idle():
    bench = Bench()
    bench.run(0.1, CarCommand.ENABLE_SC)
    bench.run(0.1, CarCommand.ENABLE_TS)
    bench.run(0.6)
    bench.run(0.1, CarCommand.ENABLE_DRIVE)
    assert bench.sim.state is AmsState.DRIVE
    bench.run(0.4, heartbeat=False)  # < heartbeat_timeout 0.5 s since the last frame
    assert bench.sim.state is AmsState.DRIVE
    bench.run(0.2, heartbeat=False)
    status = bench.last_status()
    assert status.status.state is AmsState.IDLE and relays(status) == (False, False, False)
    assert bench.sim.heartbeat_losses == 1
    assert bench.sim.pack_current_a(bench.now) == 0.0


def test_idle_needs_no_heartbeat():
    bench = Bench()
    bench.run(2.0, heartbeat=False)
    assert bench.sim.state is AmsState.IDLE and bench.sim.heartbeat_losses == 0


def test_bank_count_mismatch_is_an_error():
    bench = Bench()
    bench.run(0.1, CarCommand.ENABLE_SC)
    bench.run(0.1, CarCommand.ENABLE_TS)
    bench.run(0.6)
    bench.run(0.1, CarCommand.ENABLE_DRIVE)
    bench.run(0.2, CarCommand.NO_COMMAND, banks=2)
    events = bench.decoded(AmsErrorEvent)
    assert [e.error for e in events] == [AmsError.BANK_COUNT_MISMATCH]  # once, not per frame
    status = bench.last_status()
    assert status.status.state is AmsState.ERROR and status.status.ams_error
    assert relays(status) == (False, False, False)
    # relays at the moment of the error (in DRIVE: both AIRs closed)
    assert (status.relay_error_air_minus, status.relay_error_air_plus,
            status.relay_error_precharge) == (True, True, False)
    bench.run(0.2, CarCommand.ABORT)  # abort leaves ERROR
    assert bench.last_status().status.state is AmsState.IDLE
    assert not bench.last_status().status.ams_error


def test_override_bank_count_mismatch():
    bench = Bench()
    bench.run(0.1)
    bench.send(OverrideBankCount(3))
    bench.run(0.1)
    assert bench.decoded(AmsErrorEvent)[-1].error is AmsError.BANK_COUNT_MISMATCH


def test_charging_sequence_soc_rises():
    bench = Bench()
    bench.run(0.1, heartbeat=False)
    bench.send(ChargerCommand(ChargerStart.START, 0))
    bench.run(0.1, heartbeat=False)
    assert bench.last_status().status.state is AmsState.INIT_CHARGING
    bench.run(0.2, heartbeat=False)  # init_charging_time 0.2 s
    status = bench.last_status()
    assert status.status.state is AmsState.PRECHARGING and relays(status) == (
        False, True, True)
    bench.run(0.5, heartbeat=False)  # precharge_time; charging is not heartbeat-watched
    status = bench.last_status()
    assert status.status.state is AmsState.CHARGING and relays(status) == (True, True, False)
    assert bench.sim.pack_current_a(bench.now) == -10.0
    charger = bench.decoded(AmsChargerStatus)[-1]
    assert charger.charger_on and charger.charger_current_a == pytest.approx(10.0)
    bench.send(OverrideChargeCurrent(5.0))
    soc = bench.sim.soc
    bench.run(36.0, heartbeat=False)
    assert bench.sim.pack_current_a(bench.now) == -5.0
    assert bench.sim.soc - soc == pytest.approx(5.0 * 36.0 / 3600 / 20.0, rel=0.01)
    bench.send(ChargerCommand(ChargerStart.STOP, 0))
    bench.run(0.1, heartbeat=False)
    assert bench.last_status().status.state is AmsState.IDLE


def test_charger_start_ignored_outside_idle():
    bench = Bench()
    bench.run(0.1, CarCommand.ENABLE_SC)
    bench.send(ChargerCommand(ChargerStart.START, 0))
    bench.run(0.1, CarCommand.ENABLE_SC)
    assert bench.sim.state is AmsState.SC_ENABLED


def test_optional_charger_watchdog():
    bench = Bench(AmsSimulator(charger_timeout=0.5))
    bench.send(ChargerCommand(ChargerStart.START, 0))
    bench.run(0.4, heartbeat=False)
    assert bench.sim.state is AmsState.PRECHARGING
    bench.run(0.2, heartbeat=False)
    assert bench.sim.state is AmsState.IDLE


def drive(bench):
    for command, seconds in ((CarCommand.ENABLE_SC, 0.1), (CarCommand.ENABLE_TS, 0.6),
                             (CarCommand.ENABLE_DRIVE, 0.1)):
        bench.run(seconds, command)
    assert bench.sim.state is AmsState.DRIVE


def test_soc_and_cells_fall_while_discharging():
    bench = Bench(AmsSimulator(current_fn=lambda now: 100.0))
    drive(bench)
    soc, volts = bench.sim.soc, bench.sim.pack_voltage_v()
    bench.run(36.0)
    assert soc - bench.sim.soc == pytest.approx(100.0 * 36.0 / 3600 / 20.0, rel=0.01)
    assert bench.sim.pack_voltage_v() < volts
    cells = bench.decoded(CellVoltages)[-4:]
    values = [v for c in cells for v in c.voltages_v]
    assert all(3.6 <= v <= 4.1 for v in values)
    assert max(values) - min(values) <= 0.04  # small per-cell spread
    assert bench.last_status().soc_pct == round(bench.sim.soc * 100)


def test_periods_and_counter():
    bench = Bench(banks=2)
    bench.run(10.0)
    statuses = bench.decoded(AmsStatus)
    assert len(statuses) == 100  # 100 ms, nothing else changed the state
    assert len(bench.decoded(AmsChargerStatus)) == 100
    cells = bench.decoded(CellVoltages)
    assert len(cells) == 10 * 2 * 4  # every bank and group once a second
    assert {(c.bank, c.group) for c in cells} == {(b, g) for b in (1, 2) for g in range(4)}
    counters = [s.counter for s in statuses]
    assert counters == list(range(100))
    bench.run(16.0)
    counters = [s.counter for s in bench.decoded(AmsStatus)]
    assert counters[255:258] == [255, 0, 1]  # wraps


def test_error_code_fault():
    bench = Bench()
    bench.run(0.2)
    bench.sim.faults.error_code = int(AmsError.SHUNT_COMM)
    bench.run(0.2)
    assert [e.error for e in bench.decoded(AmsErrorEvent)] == [AmsError.SHUNT_COMM]
    assert bench.last_status().status.state is AmsState.ERROR
    bench.sim.faults.error_code = 99
    with pytest.raises(ValueError, match='not an AMS error ID'):
        bench.sim.tick(bench.now)


def test_error_while_charging_is_charge_error():
    bench = Bench()
    bench.send(ChargerCommand(ChargerStart.START, 0))
    bench.run(1.0, heartbeat=False)
    bench.sim.faults.error_code = int(AmsError.UNEXPECTED_CHARGE_RATE)
    bench.run(0.1, heartbeat=False)
    assert bench.last_status().status.state is AmsState.CHARGE_ERROR
    bench.send(ChargerCommand(ChargerStart.STOP, 0))
    bench.run(0.1, heartbeat=False)
    assert bench.sim.state is AmsState.IDLE


def test_cell_drift_fault():
    bench = Bench()
    bench.sim.faults.drift_cell = 9
    bench.sim.faults.cell_drift_v = 0.1
    bench.run(1.1)
    cells = {c.group: c.voltages_v for c in bench.decoded(CellVoltages)}
    assert cells[1][2] - cells[1][1] > 0.07  # cell 10 (group 1, k = 3) stands out
    assert bench.last_status().status.state is AmsState.IDLE
    bench.sim.faults.cell_drift_v = 0.5  # > 4.25 V: the AMS trips
    bench.run(0.2)
    assert bench.decoded(AmsErrorEvent)[-1].error is AmsError.CELL_VOLTAGE_HIGH
    assert bench.last_status().status.state is AmsState.ERROR


def test_silent_and_malformed_faults():
    bench = Bench()
    bench.sim.faults.silent = True
    bench.run(1.0)
    assert bench.frames == []
    bench.sim.faults.silent = False
    bench.sim.faults.malformed = True
    bench.run(1.0)
    assert bench.frames
    for _, frame in bench.frames:
        with pytest.raises(MalformedFrameError, match='DLC'):
            bench.codec.decode(frame.arbitration_id, frame.data)


def test_stuck_counter_fault():
    bench = Bench()
    bench.sim.faults.extra['stuck_counter'] = True
    bench.run(0.5)
    assert {s.counter for s in bench.decoded(AmsStatus)} == {0}


def test_deterministic_with_a_seed():
    runs = []
    for seed in (1, 1, 2):
        bench = Bench(AmsSimulator(seed=seed))
        bench.run(1.1)
        runs.append([f for _, f in bench.frames])
    assert runs[0] == runs[1] and runs[0] != runs[2]


def test_non_default_base_id():
    bench = Bench(base_id=0x500)
    bench.run(0.1, CarCommand.ENABLE_SC)
    assert {f.arbitration_id for _, f in bench.frames} >= {0x500, 0x501, 0x511, 0x512, 0x513}
    assert bench.sim.state is AmsState.SC_ENABLED
    bench.sim.on_frame(AmsCodec(0x300).encode(CarStatus(CarCommand.ABORT, 1, 0)), bench.now)
    assert bench.sim.state is AmsState.SC_ENABLED  # not our ID


def test_bad_frames_in_are_ignored():
    sim = AmsSimulator()
    sim.on_frame(Frame(0x305, b'\x01'), 0.0)  # wrong DLC
    sim.on_frame(Frame(0x305, b'\x01\x00', True), 0.0)  # extended: not ours
    assert sim.frames_ignored == 1 and sim.state is AmsState.IDLE


def test_bridge_device_reads_the_simulator():
    """The real AmsDevice agrees with the simulator's own pack values."""
    clock_now = [0.0]
    device = AmsDevice('ams', {'bank_count': 2}, clock=lambda: clock_now[0])
    bench = Bench(AmsSimulator(bank_count=2, current_fn=lambda now: 50.0), banks=2)
    drive(bench)
    bench.run(1.2)
    for t, frame in bench.frames:
        clock_now[0] = t
        device.handle_frame(frame.arbitration_id, frame.data, 1.0e9 + t)
    report = device.battery_report()
    assert report.present and len(report.cell_voltage) == 56
    assert report.voltage == pytest.approx(bench.sim.pack_voltage_v(), abs=56 * 0.011)
    assert report.percentage == pytest.approx(round(bench.sim.soc * 100) / 100)
    assert device.state is AmsState.DRIVE
    diag = device.diagnostic_report()
    assert diag.level == Level.OK, diag.message
    assert diag.message == 'DRIVE; AIR+ closed, AIR- closed, precharge open'


def test_padded_frames_keep_the_bridge_device_fresh():
    """--ams-pad: every frame 8 bytes; the real AmsDevice decodes them all, never stale."""
    clock_now = [0.0]
    device = AmsDevice('ams', {'bank_count': 2}, clock=lambda: clock_now[0])
    bench = Bench(AmsSimulator(bank_count=2, pad=True), banks=2)
    drive(bench)
    bench.run(1.2)
    assert bench.frames and {len(f.data) for _, f in bench.frames} == {8}
    for t, frame in bench.frames:
        clock_now[0] = t
        device.handle_frame(frame.arbitration_id, frame.data, 1.0e9 + t)
        assert not device.is_stale(), f'stale at {t:.3f} s'
    assert device.frames_malformed == 0
    report = device.battery_report()
    assert report.present and not any(math.isnan(v) for v in report.cell_voltage)
    assert device.state is AmsState.DRIVE
    # the malformed fault wins over padding: one byte short of the layout
    bench.sim.faults.malformed = True
    bench.frames = []
    bench.run(0.2)
    for _, frame in bench.frames:
        with pytest.raises(MalformedFrameError, match='DLC'):
            bench.codec.decode(frame.arbitration_id, frame.data)


def test_periodic_start_keeps_charging_under_the_charger_watchdog():
    """0x010 every 100 ms (seed 003): repeated STARTs keep CHARGING; silence ends it."""
    bench = Bench(AmsSimulator(charger_timeout=0.5, precharge_time=0.1))
    for _ in range(20):  # 2 s of START every 100 ms
        bench.send(ChargerCommand(ChargerStart.START, 0))
        bench.run(0.1, heartbeat=False)
    assert bench.sim.state is AmsState.CHARGING
    bench.run(0.6, heartbeat=False)  # the charger went silent
    assert bench.sim.state is AmsState.IDLE
