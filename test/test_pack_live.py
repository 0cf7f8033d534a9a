# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The pack through the live bridge: a BMS16 beside an EVMS3 on a virtual bus, one pack."""
import math
import threading

from std_msgs.msg import Float32
from std_srvs.srv import Trigger

from ams_can_bridge.sim.bms16 import Bms16Simulator
from ams_can_bridge.sim.evms3 import Evms3Simulator
from command_rig import battery_topics
from shared import level

FIGURES = ('charge_current_limit', 'discharge_current_limit', 'time_to_empty', 'time_to_full')


def test_the_bridge_publishes_the_pack_latches_an_msl_and_clear_events_sends_nothing(
        rig_factory):
    # every simulated cell is above 1.2 V: the MSL event is raised after its 0.5 s debounce
    params = {'devices': ['bms16', 'evms3', 'pack'], 'bms16.type': 'bms16',
              'evms3.type': 'evms3', 'pack.type': 'pack', 'pack.members': ['bms16', 'evms3'],
              'pack.max_charge_current': 40.0, 'pack.max_discharge_current': 80.0,
              'pack.max_voltage_difference': 1000.0, 'pack.max_cell_sum_difference': 1000.0,
              'pack.limits.cell_voltage_max': [1.0, 1.1, 1.2]}
    topics = battery_topics(['bms16', 'evms3', 'pack'])
    topics.update({f'pack/{suffix}': Float32 for suffix in FIGURES})
    rig = rig_factory(params, topics=topics)
    sims = [Bms16Simulator(send_sma=False, seed=1), Evms3Simulator()]
    stop = threading.Event()

    def play() -> None:  # the two batteries on the bus, 20 ms steps
        t = 0.0
        while not stop.wait(0.02):
            t += 0.02
            for sim in sims:
                for frame in sim.tick(t):
                    rig.send(frame.arbitration_id, frame.data, frame.is_extended_id)
    player = threading.Thread(target=play, daemon=True)
    player.start()
    try:
        # parallel: the mean of the BMS16's ~53 V and the EVMS3's ~96 V, known once both are
        evms3 = rig.last('evms3/battery_state', lambda m: m.present, timeout=20.0)
        both = rig.last('pack/battery_state', lambda m: m.present and math.isfinite(m.voltage),
                        timeout=20.0)
        assert 60.0 < both.voltage < 90.0
        assert len(both.cell_voltage) == 16 + len(evms3.cell_voltage)  # the BMS16's first
        status = rig.status('pack', lambda s: level(s) == 2, timeout=20.0)
        values = {kv.key: kv.value for kv in status.values}
        assert 'raised at' in values['event MSL cell_voltage_max']
        rig.last('pack/charge_current_limit', lambda m: m.data == 0.0)
        frames_out = rig.frames_out()
        answer = rig.call(Trigger, 'pack/clear_events')
        assert not answer.success
        assert answer.message.startswith('pack: still beyond: cell_voltage_max is ')
        assert rig.frames_out() == frames_out  # reporting only: nothing sent
    finally:
        stop.set()
        player.join(2)
    assert not rig.failures
