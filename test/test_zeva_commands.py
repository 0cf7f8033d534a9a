"""EVMS3 and BMS16 services on a real node: exact bytes on the bus, and every refusal."""
import contextlib
import logging

import can
import pytest
from std_srvs.srv import SetBool, Trigger


# --- BMS16: golden frames written by hand from docs/protocols.md section 4 ---------------------
BMS16_CONFIG = {
    'cells': 14.0,             # 14 (written as 14.0: YAML spelling must not matter)
    'pack_capacity_ah': 100,   # 10 Ah/bit -> 10
    'soc_warning_pct': 20,     # 20
    'full_voltage_v': 58.0,    # 58
    'warn_current_a': 150,     # 10 A/bit -> 15
    'trip_current_a': 300.0,   # 30
    'temperature_limit_c': 60,  # 60
    'min_cell_v': 2.8,         # 0.05 V/bit -> 56
    'max_cell_v': 3.65,        # 73
    'hysteresis_v': 0.1,       # 2
    'balance_v': 3.5,          # 70
    'shunt_size_a': 200,       # code 2
}
BMS16_504 = bytes([14, 10, 20, 58, 15, 30, 60, 56])
BMS16_505 = bytes([73, 2, 70, 2])


def bms16_params(enabled=True, config=BMS16_CONFIG, skip=()):
    params = {'devices': ['bms16'], 'commands_allowed': True, 'commands_enabled': enabled}
    params.update({f'bms16.config.{k}': v for k, v in config.items() if k not in skip})
    return params


def sent(rig, mark):
    return [(f.arbitration_id, f.data, f.is_extended_id) for _, f in rig.capture.since(mark)]


def test_bms16_write_config_sends_504_then_505(rig_factory):
    rig = rig_factory(bms16_params())
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/bms16/write_config')
    assert response.success, response.message
    assert rig.wait(lambda: len(sent(rig, mark)) >= 2)
    assert sent(rig, mark) == [(504, BMS16_504, False), (505, BMS16_505, False)]


@pytest.mark.parametrize('service, can_id', [('acknowledge_error', 506), ('reset_soc', 507),
                                             ('power_off', 508)])
def test_bms16_commands_without_data(rig_factory, service, can_id):
    rig = rig_factory(bms16_params(config={}))  # these need no configuration
    mark = rig.capture.mark()
    response = rig.call(Trigger, f'/bms16/{service}')
    assert response.success, response.message
    assert rig.wait(lambda: sent(rig, mark))
    assert sent(rig, mark) == [(can_id, b'', False)]


def test_bms16_write_config_names_every_missing_value_and_sends_nothing(rig_factory):
    rig = rig_factory(bms16_params(skip=('cells', 'balance_v', 'shunt_size_a')))
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/bms16/write_config')
    assert not response.success
    for name in ('cells', 'balance_v', 'shunt_size_a'):
        assert f'bms16.config.{name}' in response.message
    assert 'bms16.config.max_cell_v' not in response.message
    rig.capture.sync()  # a marker after the calls, no sleep
    assert sent(rig, mark) == []


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


def test_bms16_disabled_refuses_and_sends_nothing(rig_factory):
    rig = rig_factory(bms16_params(enabled=False))
    mark = rig.capture.mark()
    for service in ('write_config', 'acknowledge_error', 'reset_soc', 'power_off'):
        response = rig.call(Trigger, f'/bms16/{service}')
        assert not response.success and 'commands_enabled' in response.message
    rig.capture.sync()  # a marker after the calls, no sleep
    assert sent(rig, mark) == []


# --- EVMS3: golden frames written by hand from docs/protocols.md section 3 (29-bit IDs) ---------
EVMS3_CONFIG = {
    'pack_capacity_ah': 100, 'soc_warning_pct': 20, 'full_voltage_v': 400.0,
    'warn_current_a': 200, 'trip_current_a': 300, 'temp_warning_c': 60,
    'min_aux_voltage_v': 11, 'min_isolation_pct': 50,
    'tacho_ppr': 2, 'fuel_gauge_full_pct': 90, 'fuel_gauge_empty_pct': 10,
    'temp_gauge_hot_pct': 80, 'temp_gauge_cold_pct': 20, 'bms_min_cell_v': 2.8,
    'bms_max_cell_v': 3.65, 'balance_v': 3.5, 'balance_mode': 'static',
    'bms_hysteresis_v': 0.05, 'bms_min_temp_c': 0, 'bms_max_temp_c': 55,
    'max_charge_voltage_v': 400, 'max_charge_current_a': 12, 'alt_charge_voltage_v': 380,
    'alt_charge_current_a': 6, 'sleep_delay_min': 5, 'mpi_function': 1, 'mpo1_function': 2,
    'mpo2_function': 3, 'parallel_strings': 1, 'enable_precharge': True,
    'stationary_mode': False, 'cells_per_module': [12, 12, 12, 12, 8] + [0] * 11,
    'reverse_current_display': False, 'night_brightness': 10,
}
# ZEVA's Monitor order (EVMS_Monitor3.c TransmitSettings): 36 first, then 32..35; the EVMS3
# saves to EEPROM when 35 arrives, so the cell counts must come before it.
EVMS3_FRAMES = [
    # module 2n in the low nibble of byte n
    (36, bytes([0xCC, 0xCC, 0x08, 0, 0, 0, 0, 0])),
    # capacity 5 Ah/bit, SoC warn, full 2 V/bit, warn/trip 10 A/bit, temp, aux, isolation
    (32, bytes([20, 20, 200, 20, 30, 60, 11, 50])),
    # tacho, gauges, min cell 1.50 + 0.01 n, max cell 2.00 + 0.01 n, balance 2.00 + 0.01 n
    (33, bytes([2, 90, 10, 80, 20, 130, 165, 150])),
    # hysteresis 0.01 V, temps n - 40, 400 V = 0x190: low 0x90 + bit 7 of 12 A; 380 V = 0x17C
    (34, bytes([5, 40, 95, 0x90, 0x80 | 12, 0x7C, 0x80 | 6, 5])),
    # MPI, MPO1, MPO2, strings, precharge, stationary, reverse current display, brightness 10
    (35, bytes([1, 2, 3, 1, 1, 0, 0, 10])),
]
IDLE, RUNNING, SETUP = 0, 2, 5


def evms3_params(enabled=True, config=EVMS3_CONFIG, skip=()):
    params = {'devices': ['evms3'], 'commands_allowed': True, 'commands_enabled': enabled,
              'evms3.stale_timeout': 3600.0}  # one status frame keeps its state known
    params.update({f'evms3.config.{k}': v for k, v in config.items() if k not in skip})
    return params


def evms3_status(rig, state, error, b5=0x8C):
    """Put an EVMS3 status frame (ID 30) on the bus, as the EVMS would."""
    rig.capture.bus.send(can.Message(arbitration_id=30, is_extended_id=True, data=bytes(
        [state | error << 3, 0x03, 0xE8, 0x0F, 0xA0, b5, 100, 65])))


def evms3_in(rig, state, b5=0x8C):
    """Have the EVMS3 report state (0 IDLE, 5 SETUP, ...) and wait until the bridge knows."""
    evms3_status(rig, state, 0, b5)
    device = rig.node.devices['evms3']
    assert rig.wait(lambda: device.state is not None and int(device.state) == state
                    and device.status.aux_voltage_v == b5 / 10)


def refused_write_sends_nothing(rig, words):
    """Call write_config, expect a refusal naming words, prove nothing went out."""
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/evms3/write_config')
    assert not response.success, response.message
    for word in words:
        assert word in response.message, response.message
    assert 'nothing was sent' in response.message
    assert rig.call(Trigger, '/evms3/reset_soc').success  # marker: the next frame out
    assert rig.wait(lambda: sent(rig, mark))
    assert sent(rig, mark) == [(38, b'', True)]


def test_evms3_write_config_sends_36_then_32_to_35(rig_factory):
    rig = rig_factory(evms3_params())
    evms3_in(rig, IDLE)
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/evms3/write_config')
    assert response.success, response.message
    assert rig.wait(lambda: len(sent(rig, mark)) >= 5)
    assert sent(rig, mark) == [(i, data, True) for i, data in EVMS3_FRAMES]


def test_evms3_dynamic_balancing_needs_no_balance_voltage(rig_factory):
    config = dict(EVMS3_CONFIG, balance_mode='dynamic')
    rig = rig_factory(evms3_params(config=config, skip=('balance_v',)))
    evms3_in(rig, SETUP)
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/evms3/write_config')
    assert response.success, response.message
    assert rig.wait(lambda: len(sent(rig, mark)) >= 5)
    assert sent(rig, mark)[2][1][7] == 251


def test_evms3_write_config_names_every_missing_value_and_sends_nothing(rig_factory):
    missing = ('pack_capacity_ah', 'balance_v', 'stationary_mode', 'cells_per_module',
               'reverse_current_display', 'night_brightness')
    rig = rig_factory(evms3_params(skip=missing))
    evms3_in(rig, IDLE)
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/evms3/write_config')
    assert not response.success
    for name in missing:
        assert f'evms3.config.{name}' in response.message, response.message
    assert '6 configuration value(s) unset' in response.message
    rig.capture.sync()  # a marker after the calls, no sleep
    assert sent(rig, mark) == []


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
def test_evms3_write_config_refused_unless_idle_or_setup(rig_factory, state, name):
    rig = rig_factory(evms3_params())
    evms3_in(rig, state)
    refused_write_sends_nothing(rig, (f'reports {name}', 'IDLE or SETUP'))


def test_evms3_write_config_refused_before_the_evms_is_heard(rig_factory):
    rig = rig_factory(evms3_params())
    refused_write_sends_nothing(rig, ('never heard', 'IDLE or SETUP'))


def test_evms3_write_config_refused_to_a_bms16(rig_factory):
    # EVMS_Monitor3.c: ID 30 byte 5 = 255 means a BMS16 speaking the EVMS3 protocol
    rig = rig_factory(evms3_params())
    evms3_in(rig, IDLE, b5=255)
    refused_write_sends_nothing(rig, ('BMS16', 'byte 5 = 255'))


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
    from ams_can_bridge.devices.evms3 import Evms3Device
    from ams_can_bridge.engine.calls import Pipeline
    gate = _FakeGate()
    device = Evms3Device('evms3', {f'config.{k}': v for k, v in EVMS3_CONFIG.items()})
    device.handle_frame(30, bytes([IDLE, 0x03, 0xE8, 0x0F, 0xA0, 0x8C, 100, 65]), 1.0)
    pipeline = Pipeline(gate, logging.getLogger('test_zeva_commands'),
                        sleep=lambda seconds: gate.events.append(('sleep', seconds)))
    [row] = [row for row in device.COMMANDS if row.service == 'write_config']
    ok, message = pipeline.call('evms3', device, row)
    assert ok, message
    # one batch holds all five frames and their pauses: no other call's frame between them
    assert gate.events == ['batch'] + [event for can_id in (36, 32, 33, 34, 35)
                                       for event in (('tx', can_id), ('sleep', 0.02))] + ['end']


@pytest.mark.parametrize('data, payload', [(True, b'\x01'), (False, b'\x00')])
def test_evms3_set_setup_mode(rig_factory, data, payload):
    rig = rig_factory(evms3_params(config={}))
    mark = rig.capture.mark()
    response = rig.call(SetBool, '/evms3/set_setup_mode', data=data)
    assert response.success, response.message
    assert rig.wait(lambda: sent(rig, mark))
    assert sent(rig, mark) == [(31, payload, True)]


def test_evms3_reset_soc(rig_factory):
    rig = rig_factory(evms3_params(config={}))
    mark = rig.capture.mark()
    assert rig.call(Trigger, '/evms3/reset_soc').success
    assert rig.wait(lambda: sent(rig, mark))
    assert sent(rig, mark) == [(38, b'', True)]


def test_evms3_acknowledge_error_sends_the_error_reported_now(rig_factory):
    rig = rig_factory(evms3_params(config={}))
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/evms3/acknowledge_error')  # nothing heard yet: stale
    assert not response.success and 'stale' in response.message
    evms3_status(rig, state=2, error=0)
    assert rig.wait(lambda: rig.node.devices['evms3'].error is not None)
    response = rig.call(Trigger, '/evms3/acknowledge_error')
    assert not response.success and 'no error' in response.message
    rig.capture.sync()  # a marker after the refused calls, no sleep
    assert sent(rig, mark) == []
    evms3_status(rig, state=4, error=3)  # stopped, overcurrent shutdown
    assert rig.wait(lambda: int(rig.node.devices['evms3'].error) == 3)
    response = rig.call(Trigger, '/evms3/acknowledge_error')
    assert response.success, response.message
    assert rig.wait(lambda: sent(rig, mark))
    assert sent(rig, mark) == [(37, b'\x03', True)]


def test_evms3_disabled_refuses_and_sends_nothing(rig_factory):
    rig = rig_factory(evms3_params(enabled=False))
    evms3_status(rig, state=4, error=3)
    mark = rig.capture.mark()
    for srv_type, service, fields in ((Trigger, 'write_config', {}),
                                      (Trigger, 'acknowledge_error', {}),
                                      (Trigger, 'reset_soc', {}),
                                      (SetBool, 'set_setup_mode', {'data': True})):
        response = rig.call(srv_type, f'/evms3/{service}', **fields)
        assert not response.success and 'commands_enabled' in response.message
    rig.capture.sync()  # a marker after the calls, no sleep
    assert sent(rig, mark) == []
