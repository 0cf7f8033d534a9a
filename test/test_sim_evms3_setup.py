# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The simulated EVMS3 parks, enters SETUP and reports a configuration that fits its pack.

Issue 38.7: write_config can be practised without hardware.

The model on its own first, then read_config / set_setup_mode / write_config through the
bridge's command side (``bench_factory``: the one pipeline, no ROS) against the simulator
as ``simulator --evms3-state idle`` builds it (4 BMS12 modules of 12 cells, 100 Ah).
"""
import can
import pytest

from ams_can_bridge.protocols.evms3 import Evms3State, SetState
from ams_can_bridge.sim.evms3 import Evms3Simulator, FULL_CELL_V
from ams_can_bridge.sim.main import build_devices, build_parser
from ams_can_bridge.sim.runner import SimRunner


def test_key_off_parks_it_and_id_31_moves_between_idle_and_setup():
    sim = Evms3Simulator(bms12_modules=1)
    assert sim.state == Evms3State.RUNNING
    sim.on_frame(sim.codec.encode(SetState(setup=True)), 0.0)
    assert sim.state == Evms3State.RUNNING  # Setup is entered only from IDLE
    sim.key_off()
    sim.tick(0.1)
    assert sim.state == Evms3State.SETUP  # the request was kept, as the firmware keeps it
    sim.on_frame(sim.codec.encode(SetState(setup=False)), 0.2)
    assert sim.state == Evms3State.IDLE
    sim.key_on()
    assert sim.state == Evms3State.RUNNING


def test_the_simulator_option_starts_it_idle():
    args = build_parser().parse_args(['--devices', 'evms3', '--evms3-state', 'idle'])
    [sim] = build_devices(['evms3'], bms12_modules=4, evms3_state=args.evms3_state)
    assert sim.state == Evms3State.IDLE
    [sim] = build_devices(['evms3'], bms12_modules=4)
    assert sim.state == Evms3State.RUNNING
    with pytest.raises(SystemExit):
        build_parser().parse_args(['--evms3-state', 'asleep'])


@pytest.mark.parametrize('modules, capacity', [(4, 100.0), (2, 60.0), (0, 200.0)])
def test_the_configuration_it_reports_fits_its_pack(modules, capacity):
    sim = Evms3Simulator(bms12_modules=modules, capacity_ah=capacity)
    config = sim.pack_config()
    cells = 12 * modules or 96
    assert config.pack_capacity_ah == capacity
    assert abs(config.full_voltage_v - cells * FULL_CELL_V) <= 1.0
    assert config.full_voltage_v >= sim.status().pack_voltage_v  # 90 % charged: not yet full
    assert config.max_charge_voltage_v == round(cells * FULL_CELL_V)
    low, high = min(min(m) for m in sim.cell_voltages() or [[3.5]]), FULL_CELL_V
    assert config.bms_min_cell_v < low and config.bms_max_cell_v > high
    assert config.balance_mode == 'dynamic'


@pytest.fixture
def idle_evms3(bench_factory):
    """Yield (bench, simulator) for an EVMS3 started as `simulator --evms3-state idle`."""
    bench = bench_factory({'devices': ['evms3'], 'commands_allowed': True,
                           'commands_enabled': True, 'evms3.config_request': True,
                           'evms3.bms12_modules': 4})
    [sim] = build_devices(['evms3'], bms12_modules=4, evms3_state='idle')
    bus = can.Bus(interface='virtual', channel=bench.channel)
    runner = SimRunner(bus, [sim], tick_period=0.005)
    runner.start()
    yield bench, sim
    runner.stop()
    bus.shutdown()


def test_read_config_then_write_config_while_idle_and_in_setup(idle_evms3):
    bench, sim = idle_evms3
    device = bench.devices['evms3']
    assert bench.wait(lambda: device.state == Evms3State.IDLE, what='the bridge hearing IDLE')
    answer = bench.call('/evms3/read_config')
    assert answer.success, answer.message
    # the pack: 48 cells at up to 4.15 V, 100 Ah (not the firmware's 160 V defaults)
    assert 'evms3: read_config: 100 Ah, full 200 V, cells 3.00..4.20 V' in answer.message
    assert 'charge 199 V 10 A, 4 BMS12 module(s) with 48 cells' in answer.message  # 199.2
    assert device.config.value('config.full_voltage_v') == 200

    assert bench.set_param('evms3.config.soc_warning_pct', 25).successful
    answer = bench.call('/evms3/write_config')
    assert answer.success, answer.message  # IDLE: accepted
    assert bench.wait(lambda: sim.eeprom_writes == 1, what='the EVMS3 saving the config')
    assert sim.stored_config.soc_warning_pct == 25 and sim.stored_config.full_voltage_v == 200

    answer = bench.call('/evms3/set_setup_mode', True)
    assert answer.success, answer.message
    assert bench.wait(lambda: sim.state == Evms3State.SETUP, what='SETUP')
    assert bench.set_param('evms3.config.soc_warning_pct', 30).successful
    answer = bench.call('/evms3/write_config')
    assert answer.success, answer.message  # SETUP: accepted too
    assert bench.wait(lambda: sim.eeprom_writes == 2 and sim.stored_config.soc_warning_pct == 30)
    assert bench.call('/evms3/set_setup_mode', False).success
    assert bench.wait(lambda: sim.state == Evms3State.IDLE, what='IDLE again')

    sim.key_on()  # driving: the bridge refuses, nothing more is written
    assert bench.wait(lambda: device.state == Evms3State.RUNNING, what='RUNNING')
    answer = bench.call('/evms3/write_config')
    assert not answer.success and 'reports RUNNING' in answer.message
    assert sim.eeprom_writes == 2
