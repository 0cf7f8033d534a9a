# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
evms3/read_config against the simulated EVMS3 on the same virtual bus.

On a real node where the answer sets the node's parameters; the refusals, a partial answer
and the write order through the one command pipeline without ROS (``bench_factory``).

The simulator answers ID 51 like ZEVA's 2021 firmware (52..56 in the layout of 32..36). A
capture on the bus sees what each side sends: read_config then write_config must send back
exactly the frames that were read.
"""

import can
import pytest
from std_srvs.srv import Trigger

from ams_can_bridge.devices.base import device_params
from ams_can_bridge.protocols.evms3 import Evms3State
from ams_can_bridge.sim.evms3 import Evms3Simulator
from ams_can_bridge.sim.runner import SimRunner
from shared import EVMS3_ANSWER_CELLS as CELLS, EVMS3_GOLDEN_CONFIG as CONFIG

READ = '/evms3/read_config'
WRITE = '/evms3/write_config'


@pytest.fixture
def evms3_on():
    """Yield a starter of simulated EVMS3s on a rig's channel (returns the simulator)."""
    started = []

    def start(rig, **kwargs):
        bus = can.Bus(interface='virtual', channel=rig.channel)
        sim = Evms3Simulator(bms12_modules=0, **{'state': Evms3State.IDLE, **kwargs})
        runner = SimRunner(bus, [sim], tick_period=0.005)
        runner.start()
        started.append((runner, bus))
        return sim
    yield start
    for runner, bus in started:
        runner.stop()
        bus.shutdown()


def params(config_request=True, enabled=True, **more):
    return {'devices': ['evms3'], 'commands_allowed': True, 'commands_enabled': enabled,
            'evms3.config_request': config_request, **more}


def frames(rig, mark, ids):
    return [(f.arbitration_id, f.data) for _, f in rig.capture.since(mark)
            if f.arbitration_id in ids]


def config_values(bridge):
    """Return the evms3.config.* values: the node's parameters, or a bench's device's."""
    if hasattr(bridge, 'node'):
        return {name.split('.', 2)[2]: p.value for name, p in bridge.node._parameters.items()
                if name.startswith('evms3.config.')}
    device = bridge.devices['evms3']
    return {spec.key.split('.', 1)[1]: device.config.value(spec.key)
            for spec in device_params(type(device)) if spec.key.startswith('config.')}


def test_refused_without_config_request_names_it_and_sends_nothing(bench_factory, evms3_on):
    bench = bench_factory(params(config_request=False))
    sim = evms3_on(bench)
    mark = bench.capture.mark()
    response = bench.call(READ)
    assert not response.success
    assert 'evms3.config_request is false' in response.message
    assert 'throttle' in response.message and 'nothing was sent' in response.message
    bench.capture.sync()  # a marker after the calls, no sleep
    assert frames(bench, mark, {51}) == [] and sim.received == []


def test_refused_while_commands_are_disabled(bench_factory, evms3_on):
    bench = bench_factory(params(enabled=False))
    evms3_on(bench)
    mark = bench.capture.mark()
    response = bench.call(READ)
    assert not response.success and 'commands_enabled' in response.message
    bench.capture.sync()  # a marker after the calls, no sleep
    assert frames(bench, mark, {51}) == []


def test_read_config_sets_every_value_then_write_sends_back_the_same_frames(
        rig_factory, evms3_on):
    rig = rig_factory(params())
    sim = evms3_on(rig)
    sim.load(CONFIG, CELLS)  # a configured EVMS3
    assert all(v is None for v in config_values(rig).values())
    mark = rig.capture.mark()
    response = rig.call(Trigger, READ)
    assert response.success, response.message
    assert response.message == (
        'evms3: read_config: 100 Ah, full 400 V, cells 2.80..3.65 V, balance static 3.50 V, '
        'charge 300 V 30 A, 5 BMS12 module(s) with 41 cells; set 34 parameters '
        'evms3.config.*')
    assert frames(rig, mark, {51}) == [(51, b'')]
    values = config_values(rig)
    assert values['pack_capacity_ah'] == 100 and values['bms_max_cell_v'] == 3.65
    assert values['balance_mode'] == 'static' and values['balance_v'] == 3.5
    assert values['enable_precharge'] is True and list(values['cells_per_module']) == list(CELLS)
    assert values['reverse_current_display'] is True and values['night_brightness'] == 7
    read = frames(rig, mark, set(range(52, 57)))
    assert [i for i, _ in read] == [52, 53, 54, 55, 56]

    mark = rig.capture.mark()
    response = rig.call(Trigger, WRITE)
    assert response.success, response.message
    assert rig.wait(lambda: len(frames(rig, mark, set(range(32, 37)))) == 5)
    written = frames(rig, mark, set(range(32, 37)))
    assert [i for i, _ in written] == [36, 32, 33, 34, 35]  # the Monitor's order
    assert sorted((i + 20, data) for i, data in written) == read  # exactly the bytes read


def test_factory_settings_round_trip_with_dynamic_balancing(rig_factory, evms3_on):
    rig = rig_factory(params())
    evms3_on(rig)  # never configured: it reports its firmware defaults (balance 251)
    mark = rig.capture.mark()
    response = rig.call(Trigger, READ)
    assert response.success, response.message
    assert 'balance dynamic' in response.message and 'set 33 parameters' in response.message
    values = config_values(rig)
    assert values['balance_mode'] == 'dynamic' and values['balance_v'] is None
    read = frames(rig, mark, set(range(52, 57)))
    mark = rig.capture.mark()
    assert rig.call(Trigger, WRITE).success
    assert rig.wait(lambda: len(frames(rig, mark, set(range(32, 37)))) == 5)
    assert sorted((i + 20, d) for i, d in frames(rig, mark, set(range(32, 37)))) == read


def test_written_cell_counts_survive_a_power_cycle(bench_factory, evms3_on):
    # The EVMS3 saves settings and cell counts to EEPROM only when ID 35 arrives; ID 36 only
    # changes RAM. The simulator does the same: sent after 35, new counts would be lost here.
    bench = bench_factory(params())
    sim = evms3_on(bench)
    sim.load(CONFIG, CELLS)
    assert bench.call(READ).success
    new = [12, 12, 4] + [0] * 13
    assert bench.set_param('evms3.config.cells_per_module', new).successful
    assert bench.wait(lambda: bench.devices['evms3'].state is Evms3State.IDLE)
    response = bench.call(WRITE)
    assert response.success, response.message
    assert bench.wait(lambda: sim.eeprom_writes == 1)
    sim.power_cycle()
    assert sim.cell_numbers == tuple(new) and sim.stored_config == CONFIG


def test_partial_answer_fails_and_sets_nothing(bench_factory, evms3_on):
    bench = bench_factory(params(**{'evms3.read_timeout': 0.5}))
    sim = evms3_on(bench)
    sim.faults.extra['config_answer'] = [52, 53, 56]
    response = bench.call(READ)
    assert not response.success
    assert response.message == (
        'evms3: read_config failed: no complete answer within 0.5 s: incomplete: missing '
        'ID 54 (config 3), ID 55 (config 4); nothing was set')
    assert all(v is None for v in config_values(bench).values())


def test_no_answer_at_all_fails_after_read_timeout(bench_factory):
    bench = bench_factory(params(**{'evms3.read_timeout': 0.3}))  # no EVMS3 on the bus
    response = bench.call(READ)
    assert not response.success
    assert 'missing ID 52 (config 1), ID 53 (config 2), ID 54 (config 3), ID 55 (config 4), ' \
           'ID 56 (cell numbers)' in response.message


def test_parameters_are_declared_with_description_and_range(rig_factory):
    rig = rig_factory(params(config_request=False))
    [timeout] = rig.node.describe_parameters(['evms3.read_timeout'])
    assert timeout.floating_point_range[0].from_value == 0.1
    assert timeout.floating_point_range[0].to_value == 30.0
    assert '52..56' in timeout.description
    [request] = rig.node.describe_parameters(['evms3.config_request'])
    assert 'throttle' in request.description and not request.read_only
    assert rig.node.get_parameter('evms3.read_timeout').value == 2.0
    assert rig.node.get_parameter('evms3.config_request').value is False
    assert rig.set_param('evms3.read_timeout', 0.05).successful is False  # below 0.1 s
