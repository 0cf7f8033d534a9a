# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The pack's ROS-free core: each rule of doc/packs.md with exact numbers."""
import math

from ams_can_bridge.devices.base import (BatteryReport, Level, PowerSupplyHealth,
                                         PowerSupplyStatus, stale_report)
from ams_can_bridge.devices.pack.aggregate import aggregate
from ams_can_bridge.devices.pack.core import Pack, PackSettings
from ams_can_bridge.devices.pack.limits import Severity, check_levels

NAN = math.nan


def member(voltage=48.0, current=-10.0, charge=50.0, capacity=100.0, percentage=0.5,
           temperature=25.0, cells=(), temps=(25.0,), stamp=100.0,
           health=PowerSupplyHealth.GOOD):
    return BatteryReport(stamp=stamp, voltage=voltage, current=current, charge=charge,
                         capacity=capacity, design_capacity=capacity, percentage=percentage,
                         temperature=temperature, present=True, power_supply_health=health,
                         cell_voltage=list(cells), cell_temperature=list(temps))


def test_parallel_table():
    a = member(voltage=48.0, current=-10.0, charge=50.0, capacity=100.0, temperature=25.0,
               cells=(3.25, 3.5))
    b = member(voltage=49.0, current=-6.0, charge=30.0, capacity=50.0, temperature=31.0,
               cells=(3.75,), health=PowerSupplyHealth.OVERHEAT)
    r = aggregate([('a', a), ('b', b)], 'parallel')
    assert r.voltage == 48.5
    assert r.current == -16.0
    assert (r.charge, r.capacity, r.design_capacity) == (80.0, 150.0, 150.0)
    assert r.percentage == 80.0 / 150.0
    assert r.temperature == 31.0
    assert r.cell_voltage == [3.25, 3.5, 3.75]
    assert r.power_supply_status == PowerSupplyStatus.DISCHARGING
    assert r.power_supply_health == PowerSupplyHealth.OVERHEAT
    assert r.present


def test_parallel_percentage_weighted_without_charge():
    a = member(charge=NAN, capacity=100.0, percentage=0.5)
    b = member(charge=NAN, capacity=300.0, percentage=0.9)
    assert aggregate([('a', a), ('b', b)], 'parallel').percentage == (50.0 + 270.0) / 400.0
    a.capacity = NAN  # without capacities: equal weights
    assert aggregate([('a', a), ('b', b)], 'parallel').percentage == 0.7


def test_series_table():
    a = member(voltage=48.0, current=-10.0, charge=50.0, capacity=100.0, percentage=0.5)
    b = member(voltage=47.0, current=-12.0, charge=40.0, capacity=90.0, percentage=0.25,
               health=PowerSupplyHealth.DEAD)
    r = aggregate([('a', a), ('b', b)], 'series')
    assert r.voltage == 95.0
    assert r.current == -11.0
    assert (r.charge, r.capacity, r.percentage) == (40.0, 90.0, 0.25)
    assert r.power_supply_health == PowerSupplyHealth.DEAD


def test_unknown_part_makes_sum_and_mean_unknown():
    a, b = member(), member(current=NAN, voltage=NAN)
    r = aggregate([('a', a), ('b', b)], 'parallel')
    assert math.isnan(r.current) and math.isnan(r.voltage)
    assert r.power_supply_status == PowerSupplyStatus.UNKNOWN
    assert r.charge == 100.0  # the known parts still add up


def test_stale_member_named_limits_zero_and_back():
    pack = Pack(PackSettings(('a', 'b'), max_charge_current=40.0, max_discharge_current=80.0))
    out = pack.update([('a', member()), ('b', member())], 100.0)
    assert (out.charge_current_limit, out.discharge_current_limit) == (40.0, 80.0)
    assert out.warnings == []
    out = pack.update([('a', member(stamp=101.0)), ('b', stale_report(member()))], 101.0)
    assert out.warnings == ['b is stale']
    assert out.report.present  # one member still present
    assert math.isnan(out.report.current) and math.isnan(out.report.voltage)
    assert (out.charge_current_limit, out.discharge_current_limit) == (0.0, 0.0)
    diag = pack.diagnostic_report()
    assert diag.level == Level.WARN and 'b is stale' in diag.message
    out = pack.update([('a', member(stamp=102.0)), ('b', member(stamp=102.0))], 102.0)
    assert out.warnings == []
    assert (out.charge_current_limit, out.discharge_current_limit) == (40.0, 80.0)


def test_voltage_mismatch_and_cell_sum_named():
    pack = Pack(PackSettings(('a', 'b'), max_voltage_difference=1.5,
                             max_cell_sum_difference=3.0))
    a = member(voltage=48.0, cells=(3.5,) * 14)  # 49.0 V of cells: within 3 V
    b = member(voltage=46.0, cells=(3.0,) * 14)  # 42.0 V of cells against 46.0 V measured
    out = pack.update([('a', a), ('b', b)], 100.0)
    assert out.warnings == [
        'a 48.000 V and b 46.000 V differ by more than 1.5 V',
        'b: cells sum to 42.000 V, measured 46.000 V (more than 3 V apart)']
    # series members differ on purpose: no mismatch warning there
    series = Pack(PackSettings(('a', 'b'), connection='series'))
    assert series.update([('a', a), ('b', b)], 100.0).warnings == out.warnings[1:]


def test_latched_msl_refused_while_beyond_then_cleared():
    limits = {'cell_voltage_max': [4.0, 4.1, 4.2]}
    pack = Pack(PackSettings(('a',), limits=limits, debounce=0.5, max_charge_current=40.0,
                             max_discharge_current=80.0, max_cell_sum_difference=100.0))
    out = pack.update([('a', member(cells=(4.25, 3.5), stamp=10.0))], 10.0)
    assert out.raised == [] and pack.limits.events == {}  # not yet: debounce
    out = pack.update([('a', member(cells=(4.3, 3.5), stamp=10.25))], 10.25)
    assert out.raised == []
    out = pack.update([('a', member(cells=(4.27, 3.5), stamp=10.5))], 10.5)
    assert [(e.severity.name, e.raised_at, e.worst) for e in out.raised] == [
        ('MOL', 10.5, 4.27), ('RSL', 10.5, 4.27), ('MSL', 10.5, 4.27)]
    assert (out.charge_current_limit, out.discharge_current_limit) == (0.0, 0.0)
    pack.update([('a', member(cells=(4.35, 3.5), stamp=10.75))], 10.75)
    diag = pack.diagnostic_report()
    assert diag.level == Level.ERROR
    assert diag.values['event MSL cell_voltage_max'] == (
        'raised at 10.500, worst 4.35, level 4.2')
    assert pack.clear_events() == (
        False, 'still beyond: cell_voltage_max is 4.35 V, beyond the MSL 4.2 V')
    out = pack.update([('a', member(cells=(3.9, 3.5), stamp=11.0))], 11.0)
    # back inside: MOL and RSL fall, MSL stays latched and the limits stay 0
    assert list(pack.limits.events) == [('cell_voltage_max', Severity.MSL)]
    assert out.charge_current_limit == 0.0
    assert pack.clear_events() == (True, 'cleared: cell_voltage_max')
    out = pack.update([('a', member(cells=(3.9, 3.5), stamp=11.25))], 11.25)
    assert (out.charge_current_limit, out.discharge_current_limit) == (40.0, 80.0)
    assert pack.diagnostic_report().level == Level.OK


def test_short_excursion_raises_nothing():
    pack = Pack(PackSettings(('a',), limits={'temperature_max': [45.0, 50.0, 55.0]},
                             debounce=0.5))
    pack.update([('a', member(temperature=60.0, temps=(60.0,), stamp=1.0))], 1.0)
    pack.update([('a', member(temperature=30.0, temps=(30.0,), stamp=1.25))], 1.25)
    pack.update([('a', member(temperature=60.0, temps=(60.0,), stamp=1.5))], 1.5)
    assert pack.limits.events == {}


def test_derating_between_mol_and_rsl():
    limits = {'cell_voltage_max': [4.0, 4.2, 4.25], 'cell_voltage_min': [3.0, 2.8, 2.5],
              'temperature_min': [10.0, 0.0, -10.0]}
    pack = Pack(PackSettings(('a',), limits=limits, max_charge_current=40.0,
                             max_discharge_current=80.0))
    # highest cell 4.15 V: 25 % of the band left; lowest 2.85 V: 25 %; 5 degC: 50 %
    out = pack.update([('a', member(cells=(4.15, 2.85), temperature=5.0, temps=(5.0,)))], 1.0)
    assert math.isclose(out.charge_current_limit, 10.0)
    assert math.isclose(out.discharge_current_limit, 20.0)
    out = pack.update([('a', member(cells=(3.5, 3.5), temperature=5.0, temps=(5.0,)))], 2.0)
    assert (out.charge_current_limit, out.discharge_current_limit) == (20.0, 40.0)
    out = pack.update([('a', member(cells=(3.5, 3.5), temperature=20.0, temps=(20.0,)))], 3.0)
    assert (out.charge_current_limit, out.discharge_current_limit) == (40.0, 80.0)
    # an unknown cell: the limits cannot be checked, fail-safe 0
    out = pack.update([('a', member(cells=(3.5, NAN), temperature=20.0, temps=(20.0,)))], 4.0)
    assert (out.charge_current_limit, out.discharge_current_limit) == (0.0, 0.0)


def test_limits_nan_when_not_configured():
    out = Pack(PackSettings(('a',))).update([('a', member())], 1.0)
    assert math.isnan(out.charge_current_limit) and math.isnan(out.discharge_current_limit)


def test_time_to_empty_and_full_against_constant_current():
    pack = Pack(PackSettings(('a', 'b'), time_window=60.0))
    for i in range(121):  # two minutes of 10 A per member, 20 A out of the pack
        out = pack.update([('a', member(current=-10.0, charge=25.0, capacity=100.0)),
                           ('b', member(current=-10.0, charge=25.0, capacity=100.0))],
                          100.0 + i)
    assert out.time_to_empty == 50.0 * 3600.0 / 20.0  # 9000 s
    assert math.isnan(out.time_to_full)
    pack = Pack(PackSettings(('a',), time_window=60.0))
    for i in range(10):
        out = pack.update([('a', member(current=5.0, charge=90.0, capacity=100.0))], float(i))
    assert out.time_to_full == 10.0 * 3600.0 / 5.0
    assert math.isnan(out.time_to_empty)


def test_time_to_go_window_and_small_current():
    pack = Pack(PackSettings(('a',), time_window=10.0))
    for t in range(0, 11):  # 0..10 s at -20 A, then 11..20 s at -10 A: the window forgets
        pack.update([('a', member(current=-20.0, charge=10.0))], float(t))
    for t in range(11, 21):
        out = pack.update([('a', member(current=-10.0, charge=10.0))], float(t))
    # the window holds 10..20 s: one sample of -20 A and ten of -10 A
    assert out.time_to_empty == 10.0 * 3600.0 / (120.0 / 11.0)
    small = Pack(PackSettings(('a',)))
    out = small.update([('a', member(current=-0.09))], 1.0)
    assert math.isnan(out.time_to_empty) and math.isnan(out.time_to_full)
    unknown = Pack(PackSettings(('a',)))
    out = unknown.update([('a', member(current=-10.0, charge=NAN))], 1.0)
    assert math.isnan(out.time_to_empty)


def test_level_lists_checked():
    assert check_levels('cell_voltage_max', [4.0, 4.1, 4.2]) is None
    assert check_levels('cell_voltage_min', [3.0, 2.8, 2.5]) is None
    assert 'strictly increasing' in check_levels('cell_voltage_max', [4.2, 4.1, 4.0])
    assert 'strictly decreasing' in check_levels('temperature_min', [0.0, 5.0, 10.0])
    assert 'three numbers' in check_levels('temperature_max', [45.0, 50.0])


# Nav2's SimpleChargingDock (navigation2 nav2_docking/opennav_docking/src/
# simple_charging_dock.cpp) reads `battery_state` and decides charging as
# `current > charging_threshold` (default 0.5 A); power_supply_status is for the rest of ROS.
NAV2_CHARGING_THRESHOLD = 0.5


def test_the_pack_reads_as_nav2_docking_expects_charging_and_discharging():
    charging = aggregate([('a', member(current=4.0)), ('b', member(current=3.0))], 'parallel')
    assert charging.current == 7.0 and charging.current > NAV2_CHARGING_THRESHOLD
    assert charging.power_supply_status == PowerSupplyStatus.CHARGING
    driving = aggregate([('a', member(current=-4.0)), ('b', member(current=-3.0))],
                        'parallel')
    assert driving.current == -7.0 and not driving.current > NAV2_CHARGING_THRESHOLD
    assert driving.power_supply_status == PowerSupplyStatus.DISCHARGING
    # one member's current unknown: the pack's is NaN, which Nav2 reads as not charging
    unknown = aggregate([('a', member(current=4.0)), ('b', member(current=NAN))], 'parallel')
    assert math.isnan(unknown.current) and not unknown.current > NAV2_CHARGING_THRESHOLD
    assert unknown.power_supply_status == PowerSupplyStatus.UNKNOWN
