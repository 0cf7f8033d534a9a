"""EVMS3 and BMS16 services on a real node: exact bytes on the bus, and every refusal."""
import pytest
from std_srvs.srv import SetBool, Trigger

from command_rig import Rig

# --- BMS16: golden frames written by hand from PROTOCOLS.md section 4 ---------------------
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
    params = {'devices': ['bms16'], 'commands_enabled': enabled}
    params.update({f'bms16.config.{k}': v for k, v in config.items() if k not in skip})
    return params


@pytest.fixture
def rig_factory():
    rigs = []

    def make(params):
        rig = Rig(params)
        rigs.append(rig)
        return rig
    yield make
    for rig in rigs:
        rig.close()


def sent(rig, mark):
    return [(f.arbitration_id, f.data, f.is_extended_id) for _, f in rig.capture.since(mark)]


def test_bms16_write_config_sends_504_then_505(rig_factory):
    rig = rig_factory(bms16_params())
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/bms16/write_config')
    assert response.success, response.message
    assert rig.capture.wait_for(lambda: len(sent(rig, mark)) >= 2)
    assert sent(rig, mark) == [(504, BMS16_504, False), (505, BMS16_505, False)]


@pytest.mark.parametrize('service, can_id', [('acknowledge_error', 506), ('reset_soc', 507),
                                             ('power_off', 508)])
def test_bms16_commands_without_data(rig_factory, service, can_id):
    rig = rig_factory(bms16_params(config={}))  # these need no configuration
    mark = rig.capture.mark()
    response = rig.call(Trigger, f'/bms16/{service}')
    assert response.success, response.message
    assert rig.capture.wait_for(lambda: sent(rig, mark))
    assert sent(rig, mark) == [(can_id, b'', False)]


def test_bms16_write_config_names_every_missing_value_and_sends_nothing(rig_factory):
    rig = rig_factory(bms16_params(skip=('cells', 'balance_v', 'shunt_size_a')))
    mark = rig.capture.mark()
    response = rig.call(Trigger, '/bms16/write_config')
    assert not response.success
    for name in ('cells', 'balance_v', 'shunt_size_a'):
        assert f'bms16.config.{name}' in response.message
    assert 'bms16.config.max_cell_v' not in response.message
    rig.capture.wait_for(lambda: False, timeout=0.3)
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
    assert rig.capture.wait_for(lambda: len(sent(rig, mark)) >= 2)
    assert sent(rig, mark)[0][1][7] == 60  # the new 3 V min cell, 0.05 V/bit


def test_bms16_disabled_refuses_and_sends_nothing(rig_factory):
    rig = rig_factory(bms16_params(enabled=False))
    mark = rig.capture.mark()
    for service in ('write_config', 'acknowledge_error', 'reset_soc', 'power_off'):
        response = rig.call(Trigger, f'/bms16/{service}')
        assert not response.success and 'commands_enabled' in response.message
    rig.capture.wait_for(lambda: False, timeout=0.3)
    assert sent(rig, mark) == []
