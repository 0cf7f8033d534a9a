# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""SMA simulator dialects (--sma-dialect): what a Pylontech or Victron-style BMS sends."""
import pytest

from ams_can_bridge.devices.base import Level, PowerSupplyHealth
from ams_can_bridge.devices.sma.device import SmaDevice
from ams_can_bridge.protocols.sma import SmaCodec
from ams_can_bridge.sim.main import build_devices, build_parser
from ams_can_bridge.sim.sma import SmaSimulator
from helpers import run_sim


def ids(frames):
    counts = {}
    for frame in frames:
        counts[frame.arbitration_id] = counts.get(frame.arbitration_id, 0) + 1
    return counts


def test_sma_dialect_sends_no_dialect_frames():
    assert set(ids(run_sim(SmaSimulator(), None, 10.0))) == {
        0x351, 0x355, 0x356, 0x35A, 0x35E, 0x35F}


def test_pylontech_sends_0x359_and_0x35c_instead_of_0x35a():
    frames = run_sim(SmaSimulator(dialect='pylontech'), None, 10.0)
    assert ids(frames) == {0x351: 10, 0x355: 10, 0x356: 10, 0x359: 10, 0x35C: 10,
                           0x35E: 2, 0x35F: 2}
    codec = SmaCodec()
    for frame in frames:  # every frame valid
        codec.decode(frame.arbitration_id, frame.data)


def test_victron_adds_0x370_to_0x377():
    frames = run_sim(SmaSimulator(dialect='victron'), None, 10.0)
    counts = ids(frames)
    assert counts[0x35A] == 10
    assert all(counts[i] == 10 for i in range(0x372, 0x378))
    assert counts[0x370] == counts[0x371] == 2


def test_pylontech_reaches_the_device_with_alarms_and_enables():
    sim = SmaSimulator(dialect='pylontech', current_fn=lambda t: 10.0)
    device = SmaDevice('sma', {})
    run_sim(sim, device, 2.0)
    diag = device.diagnostic_report()
    assert diag.level == Level.OK
    assert diag.values['charge enable'] == 'yes' and diag.values['discharge enable'] == 'yes'
    assert diag.values['module count'] == '1' and 'alarms active' not in diag.values
    assert diag.values['bms version'] == '1.0 (bytes 2-3: 01 00)'  # as a REC Q's 02 06 is 2.6
    sim.faults.extra['alarm'] = ['high_voltage', 'contactor']  # 0x359 has no contactor bit
    sim.faults.extra['warning'] = 'low_temperature'
    run_sim(sim, device, 1.0, start=2.0)
    diag = device.diagnostic_report()
    assert diag.level == Level.ERROR
    assert diag.values['alarms active (0x359)'] == 'high_voltage'
    assert diag.values['warnings active (0x359)'] == 'low_temperature'
    assert diag.values['charge enable'] == 'no'  # over-voltage: the BMS refuses charge
    assert device.battery_report().power_supply_health == PowerSupplyHealth.OVERVOLTAGE


def test_pylontech_empty_pack_asks_for_charge():
    sim = SmaSimulator(dialect='pylontech')
    sim.soc_pct = 3.0
    sim.current_fn = lambda t: 0.0
    request = sim.pylontech_request()
    assert (request.charge_enable, request.discharge_enable,
            request.request_charge_immediately) == (True, False, True)


def test_victron_reaches_the_device_and_follows_the_drifting_cell():
    sim = SmaSimulator(dialect='victron', bms_name='ACME BATTERY 48V')
    device = SmaDevice('sma', {})
    sim.faults.drift_cell = 5
    sim.faults.cell_drift_v = 0.08
    run_sim(sim, device, 2.0)
    values = device.diagnostic_report().values
    assert values['bms name'] == 'ACME BATTERY 48V'
    assert values['max cell voltage id'] == 'C6'
    spread = float(values['max cell voltage V']) - float(values['min cell voltage V'])
    assert 0.08 - 0.008 <= spread <= 0.08 + 0.008
    assert values['modules OK'] == '1' and values['modules offline'] == '0'
    t_min = float(values['min cell temperature degC'])
    t_max = float(values['max cell temperature degC'])
    assert t_min < device.battery_report().temperature < t_max


def test_bad_dialect_and_name_are_refused():
    with pytest.raises(ValueError, match='sma, pylontech, victron'):
        SmaSimulator(dialect='byd')
    with pytest.raises(ValueError, match='1..16'):
        SmaSimulator(bms_name='A' * 17)


def test_command_line_chooses_the_dialect():
    args = build_parser().parse_args(['--devices', 'sma', '--sma-dialect', 'victron'])
    [sim] = build_devices(args.devices, sma_dialect=args.sma_dialect)
    assert sim.dialect == 'victron'
    assert build_devices(['sma'])[0].dialect == 'sma'
    with pytest.raises(SystemExit):
        build_parser().parse_args(['--sma-dialect', 'byd'])


def test_byd_soc_frame_has_zero_padding_and_the_bridge_keeps_the_soc():
    device = SmaDevice('sma', {})
    frames = run_sim(SmaSimulator(soc_layout='byd'), device, 3.0)
    socs = [f for f in frames if f.arbitration_id == 0x355]
    assert socs and all(len(f.data) == 8 and f.data[4:] == bytes(4) for f in socs)
    integer_soc = socs[-1].data[0] | socs[-1].data[1] << 8
    assert 0 < integer_soc <= 100
    assert device.battery_report().percentage == pytest.approx(integer_soc / 100)


def test_diybms_soc_frame_is_the_soc_alone():
    device = SmaDevice('sma', {})
    frames = run_sim(SmaSimulator(soc_layout='diybms'), device, 3.0)
    socs = [f for f in frames if f.arbitration_id == 0x355]
    assert socs and all(len(f.data) == 2 for f in socs)
    assert device.battery_report().percentage == pytest.approx(socs[-1].data[0] / 100)
    assert device.frames_malformed == 0


def test_command_line_chooses_the_soc_frame():
    args = build_parser().parse_args(['--devices', 'sma', '--sma-soc-frame', 'byd'])
    [sim] = build_devices(args.devices, sma_soc_frame=args.sma_soc_frame)
    assert sim.soc_layout == 'byd'
    assert build_devices(['sma'])[0].soc_layout == 'sma'
    with pytest.raises(ValueError, match='sma, byd, diybms'):
        SmaSimulator(soc_layout='pylontech')
    with pytest.raises(SystemExit):
        build_parser().parse_args(['--sma-soc-frame', 'pylontech'])


def test_tenth_volt_dialect_reaches_the_device_at_the_right_scale():
    # as a Discover Lynx II sends it: 0x356 in 0.1 V, 0x351 limits (always 0.1 V) beside it
    sim = SmaSimulator(voltage_scale=0.1, current_fn=lambda t: 0.0)
    device = SmaDevice('sma', {})
    frames = run_sim(sim, device, 3.0)
    raw = [int.from_bytes(f.data[:2], 'little') for f in frames if f.arbitration_id == 0x356]
    assert raw and abs(raw[-1] / 10 - sim.voltage_v()) <= 0.06  # 52.4 V sent as 524
    assert device.battery_report().voltage == pytest.approx(sim.voltage_v(), abs=0.06)
    assert device.diagnostic_report().values['voltage scale (0x356)'].startswith(
        '0.1 V/bit (auto: ')
    with pytest.raises(ValueError, match='0.01, 0.1'):
        SmaSimulator(voltage_scale=1.0)


@pytest.mark.parametrize('dialect, capacity', [('sma', None), ('victron', 100.0)])
def test_capacity_zero_is_not_sent_and_victron_sends_0x379(dialect, capacity):
    sim = SmaSimulator(dialect=dialect, send_capacity=False)
    device = SmaDevice('sma', {})
    frames = run_sim(sim, device, 6.0)
    infos = [f for f in frames if f.arbitration_id == 0x35F]
    assert infos and all(f.data[4:6] == bytes(2) for f in infos)  # capacity 0: as Eco-Worthy
    report = device.battery_report()
    if capacity is None:
        assert report.capacity != report.capacity  # NaN: not sent
    else:
        assert report.capacity == capacity  # from the installed capacity 0x379


def test_command_line_chooses_the_voltage_scale_and_capacity():
    args = build_parser().parse_args(['--devices', 'sma', '--sma-voltage-scale', '0.1',
                                      '--sma-no-capacity'])
    [sim] = build_devices(args.devices, sma_voltage_scale=args.sma_voltage_scale,
                          sma_no_capacity=args.sma_no_capacity)
    assert sim.voltage_scale == 0.1 and sim.send_capacity is False
    [sim] = build_devices(['sma'])
    assert sim.voltage_scale == 0.01 and sim.send_capacity is True
    with pytest.raises(SystemExit):
        build_parser().parse_args(['--sma-voltage-scale', '1'])
