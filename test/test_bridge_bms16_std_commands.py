# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
BMS16 standard form: telemetry, services and their refusals.

Telemetry on a real node; the services through the one command pipeline without ROS
(``bench_factory``), on a virtual bus. write_config sends IDs 36, 32..35, 20 ms apart as
ZEVA's Monitor sends them; power off is 39, acknowledge 37, reset SoC 38. Golden frames:
shared.py (BMS16_STD_*, written by hand from the Monitor firmware).
"""
import can

from command_rig import battery_topics
from shared import (BMS16_STD_CONFIG as CONFIG, BMS16_STD_EVMS3_STATUS as EVMS3_STATUS,
                    BMS16_STD_STATUS as STATUS, BMS16_STD_WRITE as GOLDEN_WRITE, sent)


def params(enabled=True, config=CONFIG):
    out = {'devices': ['bms16'], 'bms16.variant': 'standard', 'commands_allowed': True,
           'commands_enabled': enabled}
    out.update({f'bms16.config.{k}': v for k, v in config.items()})
    return out


def sent_after(bridge, mark):
    """Frames the bridge sent after mark, up to a marker frame (Capture.sync): none is late."""
    bridge.capture.sync()
    return sent(bridge, mark)


def heard(bridge):
    bridge.send(30, STATUS, extended=True)
    bridge.wait(lambda: not bridge.devices['bms16'].is_stale(), what='the BMS16 status')


def test_status_reaches_battery_state(rig_factory):
    rig = rig_factory(params(enabled=False), topics=battery_topics(['bms16']))
    rig.send(30, STATUS, extended=True)
    msg = rig.last('bms16/battery_state', lambda m: m.present)
    assert round(msg.voltage, 3) == 52.8 and round(msg.charge, 3) == 123.4
    assert round(msg.percentage, 4) == round(123.4 / 200, 4)  # config.pack_capacity_ah 200


def test_write_config_sends_36_then_32_to_35_paced(bench_factory):
    bench = bench_factory(params())
    heard(bench)
    listener = can.Bus(interface='virtual', channel=bench.channel)  # its timestamps: send time
    try:
        mark = bench.capture.mark()
        response = bench.call('/bms16/write_config')
        assert response.success, response.message
        assert sent_after(bench, mark) == [(i, d, True) for i, d in GOLDEN_WRITE]
        stamps = []
        while len(stamps) < len(GOLDEN_WRITE):
            msg = listener.recv(2.0)
            assert msg is not None, 'the write did not reach the listener'
            if 32 <= msg.arbitration_id <= 36:
                stamps.append(msg.timestamp)
        gaps = [b - a for a, b in zip(stamps, stamps[1:])]
        assert min(gaps) >= 0.019, gaps  # the Monitor's CanTX(..., 20): 20 ms after each
    finally:
        listener.shutdown()


def test_write_config_refused_while_only_an_evms3_is_heard(bench_factory):
    bench = bench_factory(params())
    bench.send(30, EVMS3_STATUS, extended=True)
    bench.wait(lambda: bench.devices['bms16'].frames_malformed, what='the EVMS3 status')
    mark = bench.capture.mark()
    response = bench.call('/bms16/write_config')
    assert not response.success and 'byte 5 = 255' in response.message
    assert sent_after(bench, mark) == []


def test_write_config_names_missing_values_and_sends_nothing(bench_factory):
    bench = bench_factory(params(config={k: v for k, v in CONFIG.items() if k != 'cells'}))
    heard(bench)
    mark = bench.capture.mark()
    response = bench.call('/bms16/write_config')
    assert not response.success and 'bms16.config.cells' in response.message
    assert sent_after(bench, mark) == []


def test_maintenance_frames(bench_factory):
    bench = bench_factory(params(config={}))
    heard(bench)
    for service, frame in (('power_off', (39, b'', True)), ('reset_soc', (38, b'', True)),
                           ('acknowledge_error', (37, b'\x0a', True))):
        mark = bench.capture.mark()
        response = bench.call(f'/bms16/{service}')
        assert response.success, response.message
        assert sent_after(bench, mark) == [frame], service


def test_nothing_sent_while_commands_disabled(bench_factory):
    bench = bench_factory(params(enabled=False))
    heard(bench)
    mark = bench.capture.mark()
    for service in ('write_config', 'power_off'):
        response = bench.call(f'/bms16/{service}')
        assert not response.success and 'commands_enabled' in response.message
    assert sent_after(bench, mark) == []


def test_config_parameters_refuse_values_outside_the_monitors_ranges(rig_factory):
    rig = rig_factory(params())
    for name, value in (('cells', 7), ('full_voltage_v', 71), ('pack_capacity_ah', 1252),
                        ('shunt_size_a', 250)):
        result = rig.set_param(f'bms16.config.{name}', value)
        assert not result.successful and f'bms16.config.{name}' in result.reason
