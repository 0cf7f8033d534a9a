# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
EVMS3 and BMS16 services: exact bytes on the bus, and every refusal.

Through the one command pipeline without ROS (``bench_factory``: the bridge's command side on
a python-can virtual bus), except the parameter refusals, which are rclpy's ranges and the
device's checks on a real node. Golden frames: shared.py, written by hand from
doc/protocols.md sections 3 and 4.
"""
import contextlib
import logging

import pytest
from std_srvs.srv import Trigger

from shared import (BMS16_504, BMS16_505, bms16_params, EVMS3_CONFIG, EVMS3_FRAMES,
                    evms3_in, evms3_params, evms3_status, IDLE, RUNNING, SETUP, sent)


def test_bms16_write_config_sends_504_then_505(bench_factory):
    bench = bench_factory(bms16_params())
    mark = bench.capture.mark()
    response = bench.call('/bms16/write_config')
    assert response.success, response.message
    assert bench.wait(lambda: len(sent(bench, mark)) >= 2)
    assert sent(bench, mark) == [(504, BMS16_504, False), (505, BMS16_505, False)]


@pytest.mark.parametrize('service, can_id', [('acknowledge_error', 506), ('reset_soc', 507),
                                             ('power_off', 508)])
def test_bms16_commands_without_data(bench_factory, service, can_id):
    bench = bench_factory(bms16_params(config={}))  # these need no configuration
    mark = bench.capture.mark()
    response = bench.call(f'/bms16/{service}')
    assert response.success, response.message
    assert bench.wait(lambda: sent(bench, mark))
    assert sent(bench, mark) == [(can_id, b'', False)]


def test_bms16_write_config_names_every_missing_value_and_sends_nothing(bench_factory):
    bench = bench_factory(bms16_params(skip=('cells', 'balance_v', 'shunt_size_a')))
    mark = bench.capture.mark()
    response = bench.call('/bms16/write_config')
    assert not response.success
    for name in ('cells', 'balance_v', 'shunt_size_a'):
        assert f'bms16.config.{name}' in response.message
    assert 'bms16.config.max_cell_v' not in response.message
    bench.capture.sync()  # a marker after the calls, no sleep
    assert sent(bench, mark) == []


def test_bms16_config_refuses_out_of_range_and_off_step_values(rig_factory):
    rig = rig_factory(bms16_params())
    # the reason names the parameter and what is allowed (rclpy's range text or ours)
    for name, value, allowed in (('min_cell_v', 0.5, ('Min: 1.0', 'Max: 5.0')),
                                 ('min_cell_v', 2.81, ('step: 0.05',)),
                                 ('cells', 17, ('Min: 12', 'Max: 16')),
                                 ('cells', 13.5, ('whole number',)),
                                 ('shunt_size_a', 250, ('100, 200 or 500 A',))):
        result = rig.set_param(f'bms16.config.{name}', value)
        assert not result.successful
        assert f'bms16.config.{name}' in result.reason
        assert all(text in result.reason for text in allowed), result.reason
    assert rig.set_param('bms16.config.min_cell_v', 3).successful  # int for a float: fine
    mark = rig.capture.mark()
    assert rig.call(Trigger, '/bms16/write_config').success
    assert rig.wait(lambda: len(sent(rig, mark)) >= 2)
    assert sent(rig, mark)[0][1][7] == 60  # the new 3 V min cell, 0.05 V/bit


def test_bms16_disabled_refuses_and_sends_nothing(bench_factory):
    bench = bench_factory(bms16_params(enabled=False))
    mark = bench.capture.mark()
    for service in ('write_config', 'acknowledge_error', 'reset_soc', 'power_off'):
        response = bench.call(f'/bms16/{service}')
        assert not response.success and 'commands_enabled' in response.message
    bench.capture.sync()  # a marker after the calls, no sleep
    assert sent(bench, mark) == []


# --- EVMS3: golden frames in shared.py, written by hand from doc/protocols.md section 3 ---
def refused_write_sends_nothing(bench, words):
    """Call write_config, expect a refusal naming words, prove nothing went out."""
    mark = bench.capture.mark()
    response = bench.call('/evms3/write_config')
    assert not response.success, response.message
    for word in words:
        assert word in response.message, response.message
    assert 'nothing was sent' in response.message
    assert bench.call('/evms3/reset_soc').success  # marker: the next frame out
    assert bench.wait(lambda: sent(bench, mark))
    assert sent(bench, mark) == [(38, b'', True)]


def test_evms3_write_config_sends_36_then_32_to_35(bench_factory):
    bench = bench_factory(evms3_params())
    evms3_in(bench, IDLE)
    mark = bench.capture.mark()
    response = bench.call('/evms3/write_config')
    assert response.success, response.message
    assert bench.wait(lambda: len(sent(bench, mark)) >= 5)
    assert sent(bench, mark) == [(i, data, True) for i, data in EVMS3_FRAMES]


def test_evms3_dynamic_balancing_needs_no_balance_voltage(bench_factory):
    config = dict(EVMS3_CONFIG, balance_mode='dynamic')
    bench = bench_factory(evms3_params(config=config, skip=('balance_v',)))
    evms3_in(bench, SETUP)
    mark = bench.capture.mark()
    response = bench.call('/evms3/write_config')
    assert response.success, response.message
    assert bench.wait(lambda: len(sent(bench, mark)) >= 5)
    assert sent(bench, mark)[2][1][7] == 251


def test_evms3_write_config_names_every_missing_value_and_sends_nothing(bench_factory):
    missing = ('pack_capacity_ah', 'balance_v', 'stationary_mode', 'cells_per_module',
               'reverse_current_display', 'night_brightness')
    bench = bench_factory(evms3_params(skip=missing))
    evms3_in(bench, IDLE)
    mark = bench.capture.mark()
    response = bench.call('/evms3/write_config')
    assert not response.success
    for name in missing:
        assert f'evms3.config.{name}' in response.message, response.message
    assert '6 configuration value(s) unset' in response.message
    bench.capture.sync()  # a marker after the calls, no sleep
    assert sent(bench, mark) == []


def test_evms3_config_refusals_name_the_allowed_range(rig_factory):
    rig = rig_factory(evms3_params())
    for name, value, allowed in (
            ('pack_capacity_ah', 7, ('step',)), ('full_voltage_v', 504, ('502',)),
            ('balance_mode', 'fast', ('static', 'dynamic', 'off')),
            ('cells_per_module', [12] * 15, ('16',)),
            ('cells_per_module', [13] + [0] * 15, ('12',)),
            ('cells_per_module', [2] + [0] * 15, ('4..12',)),
            ('min_aux_voltage_v', 17, ('16',)), ('night_brightness', 11, ('10',))):
        result = rig.set_param(f'evms3.config.{name}', value)
        assert not result.successful, name
        assert f'evms3.config.{name}' in result.reason, result.reason
        assert all(text in result.reason for text in allowed), result.reason
    assert rig.set_param('evms3.config.full_voltage_v', 402).successful  # 402 = 201 x 2 V
    assert rig.set_param('evms3.config.min_aux_voltage_v', 16).successful  # Common.h max 16
    evms3_in(rig, IDLE)
    mark = rig.capture.mark()
    assert rig.call(Trigger, '/evms3/write_config').success
    assert rig.wait(lambda: len(sent(rig, mark)) >= 5)
    assert sent(rig, mark)[1][1][2] == 201 and sent(rig, mark)[1][1][6] == 16


@pytest.mark.parametrize('state,name', [(1, 'PRECHARGING'), (RUNNING, 'RUNNING'),
                                        (3, 'CHARGING'), (4, 'STOPPED')])
def test_evms3_write_config_refused_unless_idle_or_setup(bench_factory, state, name):
    bench = bench_factory(evms3_params())
    evms3_in(bench, state)
    refused_write_sends_nothing(bench, (f'reports {name}', 'IDLE or SETUP'))


def test_evms3_write_config_refused_before_the_evms_is_heard(bench_factory):
    bench = bench_factory(evms3_params())
    refused_write_sends_nothing(bench, ('never heard', 'IDLE or SETUP'))


def test_evms3_write_config_refused_to_a_bms16(bench_factory):
    # EVMS_Monitor3.c: ID 30 byte 5 = 255 means a BMS16 speaking the EVMS3 protocol
    bench = bench_factory(evms3_params())
    evms3_in(bench, IDLE, b5=255)
    refused_write_sends_nothing(bench, ('BMS16', 'byte 5 = 255'))


class _FakeGate:
    """Just enough gate for the pipeline: records transmits and sleeps in one timeline."""

    enabled = True

    def __init__(self):
        self.events = []

    @contextlib.contextmanager
    def calling(self, source):
        yield

    def wait_for_bus(self, limit=None):
        return True, ''

    @contextlib.contextmanager
    def batch(self):
        self.events.append('batch')
        yield
        self.events.append('end')

    def transmit(self, frame, wait=False):
        self.events.append(('tx', frame.arbitration_id))
        return True, 'sent'


def test_evms3_write_config_paces_20_ms_after_each_frame():
    # EVMS_Monitor3.c TransmitSettings: CanTX(id, data, 8, 20) = 20 ms after each frame
    from ams_can_bridge.devices.evms3.device import Evms3Device
    from ams_can_bridge.engine.commands import Pipeline
    gate = _FakeGate()
    device = Evms3Device('evms3', {f'config.{k}': v for k, v in EVMS3_CONFIG.items()})
    device.handle_frame(30, bytes([IDLE, 0x03, 0xE8, 0x0F, 0xA0, 0x8C, 100, 65]), 1.0)
    pipeline = Pipeline(gate, logging.getLogger('test_bridge_zeva_commands'),
                        sleep=lambda seconds: gate.events.append(('sleep', seconds)))
    [row] = [row for row in device.COMMANDS if row.service == 'write_config']
    ok, message = pipeline.call('evms3', device, row)
    assert ok, message
    # one batch holds all five frames and their pauses: no other call's frame between them
    assert gate.events == ['batch'] + [event for can_id in (36, 32, 33, 34, 35)
                                       for event in (('tx', can_id), ('sleep', 0.02))] + ['end']


@pytest.mark.parametrize('data, payload', [(True, b'\x01'), (False, b'\x00')])
def test_evms3_set_setup_mode(bench_factory, data, payload):
    bench = bench_factory(evms3_params(config={}))
    mark = bench.capture.mark()
    response = bench.call('/evms3/set_setup_mode', data)
    assert response.success, response.message
    assert bench.wait(lambda: sent(bench, mark))
    assert sent(bench, mark) == [(31, payload, True)]


def test_evms3_reset_soc(bench_factory):
    bench = bench_factory(evms3_params(config={}))
    mark = bench.capture.mark()
    assert bench.call('/evms3/reset_soc').success
    assert bench.wait(lambda: sent(bench, mark))
    assert sent(bench, mark) == [(38, b'', True)]


def test_evms3_acknowledge_error_sends_the_error_reported_now(bench_factory):
    bench = bench_factory(evms3_params(config={}))
    mark = bench.capture.mark()
    response = bench.call('/evms3/acknowledge_error')  # nothing heard yet: stale
    assert not response.success and 'stale' in response.message
    evms3_status(bench, state=2, error=0)
    assert bench.wait(lambda: bench.devices['evms3'].error is not None)
    response = bench.call('/evms3/acknowledge_error')
    assert not response.success and 'no error' in response.message
    bench.capture.sync()  # a marker after the refused calls, no sleep
    assert sent(bench, mark) == []
    evms3_status(bench, state=4, error=3)  # stopped, overcurrent shutdown
    assert bench.wait(lambda: int(bench.devices['evms3'].error) == 3)
    response = bench.call('/evms3/acknowledge_error')
    assert response.success, response.message
    assert bench.wait(lambda: sent(bench, mark))
    assert sent(bench, mark) == [(37, b'\x03', True)]


def test_evms3_disabled_refuses_and_sends_nothing(bench_factory):
    bench = bench_factory(evms3_params(enabled=False))
    evms3_status(bench, state=4, error=3)
    mark = bench.capture.mark()
    for service, data in (('write_config', None), ('acknowledge_error', None),
                          ('reset_soc', None), ('set_setup_mode', True)):
        response = bench.call(f'/evms3/{service}', data)
        assert not response.success and 'commands_enabled' in response.message
    bench.capture.sync()  # a marker after the calls, no sleep
    assert sent(bench, mark) == []
