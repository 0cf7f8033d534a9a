# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The demo: its renderer with known data, and the installed `demo` executable end to end."""
import math
import os
import re
import subprocess

import pytest

from ams_can_bridge.ros.demo_view import (
    cell_range, COLUMNS, device_row, DeviceRow, fmt_uptime, level_name, render, View,
    without_readings)
from executables import package_executable

NAN = math.nan
ANSI = re.compile(r'\033\[[0-9;?]*[A-Za-z]')
DEVICES = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma')


def known_view() -> View:
    return View(
        bus='virtual:demo', uptime_s=3723.9, frames_in=12345, frames_out=67,
        bus_state='connected', bus_level='OK',
        rows=[
            DeviceRow('ams', 'ams', 'DRIVE', 403.25, -45.16, 0.8734, 3.6012, 3.652, 31.04,
                      'OK', 'DRIVE, no errors'),
            DeviceRow('bms16', 'bms16', '', NAN, NAN, NAN, NAN, NAN, NAN, 'STALE',
                      'no status frame for 1.25 s'),
            DeviceRow('sma', 'sma', 'ALARM', 51.2, 12.0, 1.0, NAN, NAN, -5.0, 'ERROR', ''),
        ],
        last_command='enable_drive', last_answer='OK in 0.31 s: DRIVE')


def table(text: str) -> list[str]:
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith('DEVICE'))
    return lines[start:start + 4]


def test_render_plain_aligns_columns_units_and_nan():
    text = render(known_view(), colour=False, unicode=False)
    assert '\033[' not in text
    header, ams, bms16, sma = table(text)
    # Every column starts at the same offset in the header and in the rows.
    starts = [header.index(title) for title, _, _ in COLUMNS]
    assert starts == sorted(starts)
    assert ams.split() == ['ams', 'DRIVE', '403.2', 'V', '-45.2', 'A', '87.3', '%',
                           '3.601..3.652', 'V', '31.0', 'C', 'OK']
    # Right-aligned numbers end where their header ends.
    volt_end = header.index('VOLTAGE') + len('VOLTAGE')
    assert ams[:volt_end].endswith('403.2 V')
    assert bms16[:volt_end].endswith('n/a')
    assert bms16.split() == ['bms16'] + ['n/a'] * 6 + ['STALE']
    assert sma.split()[-1] == 'ERROR' and '100.0 %' in sma and '-5.0 C' in sma
    assert 'nan' not in text.lower().replace('n/a', '')
    assert 'uptime 1:02:03' in text
    assert 'frames in 12345 / out 67' in text
    assert 'last command: enable_drive -> OK in 0.31 s: DRIVE' in text
    assert '  bms16: no status frame for 1.25 s' in text


def test_render_colour_keeps_alignment_and_colours_levels():
    plain = render(known_view(), colour=False, unicode=True)
    coloured = render(known_view(), colour=True, unicode=True)
    assert ANSI.sub('', coloured) == plain
    assert '\u2014' in plain and '\u00b0C' in plain and 'n/a' not in plain
    rows = {line.split()[0]: line for line in coloured.splitlines()
            if line.split() and line.split()[0] in ('ams', 'bms16', 'sma')}
    assert '\033[32mOK' in rows['ams']          # green OK
    assert '\033[35mSTALE' in rows['bms16']     # magenta STALE
    assert '\033[31;1mERROR' in rows['sma']     # red ERROR
    assert '\033[32;1mDRIVE' in rows['ams']     # the state the demo walks to


def test_render_before_any_data():
    view = View(rows=[DeviceRow(name, name) for name in DEVICES])
    text = render(view, unicode=False)
    assert 'no status yet' in text and 'last command: none yet' in text
    for name in DEVICES:
        assert re.search(rf'^{name}\s+(n/a\s+){{6}}n/a$', text, re.M), name


def test_every_line_fits_80_columns():
    """Issue 18: the demo view fits a default terminal, whatever the bus name or message."""
    view = known_view()
    view.bus = 'virtual:ams_can_bridge_demo_29842_7ff426b84dd0_and_then_some_more'
    view.bus_state = 'reconnecting: ' + 'a long reason from python-can ' * 4
    view.rows.append(DeviceRow('evms3', 'evms3', 'PRECHARGING', 403.2, -109.9, 1.0, 3.0,
                               4.2, -25.0, 'WARN', 'RUNNING, ' + 'warning text ' * 10))
    view.last_answer = 'OK in 0.07 s: ams: ENABLE_DRIVE: AMS reports DRIVE ' * 3
    view.notes = ['a note ' * 20]
    for colour in (False, True):
        for unicode in (False, True):
            lines = ANSI.sub('', render(view, colour=colour, unicode=unicode)).splitlines()
            assert max(len(line) for line in lines) <= 80, [
                line for line in lines if len(line) > 80]
    assert 'bus virtual:ams_can_bridge_demo_' in render(view)  # cut, not dropped


def test_helpers():
    assert cell_range([NAN, 3.5, 3.2, NAN]) == (3.2, 3.5)
    assert all(math.isnan(v) for v in cell_range([NAN, NAN]))
    assert all(math.isnan(v) for v in cell_range([]))
    assert [level_name(b) for b in (b'\x00', b'\x01', b'\x02', b'\x03')] == [
        'OK', 'WARN', 'ERROR', 'STALE']
    assert level_name(2) == 'ERROR' and level_name(None) == ''
    assert fmt_uptime(59.9) == '0:00:59' and fmt_uptime(3600) == '1:00:00'


def currents(text: str, name: str) -> list[str]:
    """Return every current shown for one device: in its row and in its summary line."""
    return [value for line in text.splitlines()
            if line.startswith(f'{name} ') or line.startswith(f'  {name}: ')
            for value in re.findall(r'[-+]?\d+\.\d+ A\b', line)]


def test_one_device_shows_one_current_though_its_diagnostics_lag():
    """
    Issue 31: the row's current (battery_state) and the summary's (diagnostics) differed.

    Real messages as the bridge publishes them: battery_state with every frame, the
    diagnostics message of the IVT-S ('<I> A, <U> V') and BMS16 ('OK; SoC .., .. V, .. A')
    from the last diagnostics period, when the current was another.
    """
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    from sensor_msgs.msg import BatteryState

    def status(message, level=b'\x00', **values):
        return DiagnosticStatus(level=level, name='ams_can_bridge: x', message=message,
                                values=[KeyValue(key=k, value=v) for k, v in values.items()])
    battery = BatteryState(voltage=222.1, current=-27.7, percentage=0.8, temperature=25.0)
    view = View(rows=[
        device_row('ivt_s', battery, status('-30.05 A, 222.9 V')),
        device_row('bms16', battery, status('error LOW_CELL; SoC 80 %, 52.9 V, -40.7 A',
                                            b'\x02')),
        device_row('ams', battery, status('DRIVE; AIR+ closed, AIR- closed, precharge open',
                                          state='DRIVE')),
        device_row('shunt', battery, status('over-current (OCS) tripped (I); -30.05 A, 222.9 V',
                                            b'\x01')),
    ])
    text = render(view, unicode=False)
    for name in ('ivt_s', 'bms16', 'ams', 'shunt'):
        assert currents(text, name) == ['-27.7 A'], (name, text)
    # what the table does not show stays: in the STATE column or the summary line
    assert 'ivt_s:' not in text and 'bms16:' not in text  # nothing beyond the row
    assert table(text)[2].split()[1:3] == ['error', 'LOW_CELL']
    assert '  ams: DRIVE; AIR+ closed, AIR- closed, precharge open' in text
    assert '  shunt: over-current (OCS) tripped (I)\n' in text
    assert without_readings('OK; SoC 80 %, 52.9 V, -40.7 A') == 'OK'
    assert without_readings('result stopped (U2); nan A, nan V') == 'result stopped (U2)'
    assert without_readings('BMS error 3; 12.5 A') == 'BMS error 3'  # a dbc level message
    assert without_readings('stale: no frame for 1.25 s (stale_timeout 1 s)') == (
        'stale: no frame for 1.25 s (stale_timeout 1 s)')


def demo_executable() -> str:
    return package_executable('demo')


def snapshots(output: str) -> list[str]:
    return [part for part in output.split('--- t = ') if part.strip()][1:]


def rows_of(snapshot: str) -> dict[str, list[str]]:
    rows = {}
    for line in snapshot.splitlines():
        words = line.split()
        if len(words) > 2 and words[0] in DEVICES:
            rows[words[0]] = words
    return rows


@pytest.mark.slow
def test_installed_demo_runs_drives_the_ams_and_exits_cleanly():
    env = dict(os.environ)  # conftest: LOCALHOST discovery, a domain of this run
    result = subprocess.run([demo_executable(), '--duration', '10', '--plain'],
                            capture_output=True, text=True, timeout=60, env=env)
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-3000:]
    assert 'Traceback' not in output, output[-3000:]
    shots = snapshots(result.stdout)
    assert len(shots) >= 5, result.stdout[-3000:]
    last = rows_of(shots[-1])
    assert set(last) == set(DEVICES), shots[-1]
    for name, words in last.items():
        numbers = [w for w in words[2:] if re.fullmatch(r'-?\d+\.\d+', w)]
        assert numbers, f'{name} shows no numbers: {words}'
    assert 'OK (connected)' in shots[-1]
    for shot in shots:  # issue 31: one current per device, not one more in its summary
        for name in DEVICES:
            assert len(currents(shot, name)) <= 1, shot
    # The AMS state column over time: it reached DRIVE, and IDLE after the abort.
    states = [rows_of(shot).get('ams', ['', ''])[1] for shot in shots]
    assert 'DRIVE' in states, states
    assert 'IDLE' in states[states.index('DRIVE'):], states
    assert 'abort -> OK' in result.stdout, result.stdout[-3000:]


def test_demo_rig_detects_the_misconfigured_ivt_s():
    # demo --misconfigured-ivt: the simulated IVT-S sends little-endian, the bridge expects
    # big-endian; check_config_at_start reads the sensor and the status names the parameter.
    from ams_can_bridge.devices.base import Level
    from ams_can_bridge.ros.demo_rig import DemoRig
    from helpers import ros_context, wait_for
    with ros_context() as context:
        rig = DemoRig(banks=1, misconfigured_ivt=True, context=context)
        try:
            device = rig.bridge.devices['ivt_s']
            report = wait_for(lambda: (lambda r: r if r.level == Level.ERROR else None)(
                device.diagnostic_report()), 15.0, 'the ivt_s ERROR')
            assert 'set ivt_s.byte_order to little' in report.message
        finally:
            rig.close()


@pytest.mark.slow
def test_the_demo_keeps_to_its_own_bridge_beside_a_foreign_one(rig_factory):
    """
    Issue 38.3: another bridge on the same domain, in the root namespace as the demo's was.

    The foreign bridge has an AMS that never speaks (STALE rows at 1 Hz) and commands
    disabled (every call answered REFUSED): neither may reach the demo's view or its loop.
    """
    from sensor_msgs.msg import BatteryState
    foreign = rig_factory({'devices': ['ams', 'ivt_s'], 'commands_allowed': True},
                          topics={'ams/battery_state': BatteryState})
    assert foreign.wait(lambda: foreign.messages('ams/battery_state'), 30.0), \
        'the foreign bridge publishes no stale ams/battery_state'
    result = subprocess.run([demo_executable(), '--duration', '12', '--plain'],
                            capture_output=True, text=True, timeout=90, env=dict(os.environ))
    assert result.returncode == 0, (result.stdout + result.stderr)[-3000:]
    shots = snapshots(result.stdout)
    assert 'ams_can_bridge demo /demo_' in shots[-1]
    assert 'REFUSED' not in result.stdout and 'commands_enabled' not in result.stdout
    shown = [rows_of(shot).get('ams', ['', ''])[1] for shot in shots]
    first = next(i for i, state in enumerate(shown) if state not in ('', 'n/a', '—'))
    assert 'STALE' not in ' '.join(' '.join(rows_of(s).get('ams', [])) for s in shots[first:])
    assert 'DRIVE' in shown and 'abort -> OK' in result.stdout, result.stdout[-3000:]
    assert foreign.frames_out() == 0  # commands disabled: the foreign bridge sent nothing


def test_a_pack_row_shows_its_limits_time_to_go_and_events():
    """The pack's limits and time-to-go come from its diagnostics values, beside its events."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    from sensor_msgs.msg import BatteryState
    values = {'members': 'bms16, evms3', 'connection': 'parallel',
              'charge_current_limit': '0', 'discharge_current_limit': '120.5',
              'time_to_empty': '9000', 'time_to_full': 'nan',
              'event MSL cell_voltage_max': 'raised at 12.000, worst 4.31, level 4.25'}
    status = DiagnosticStatus(level=b'\x02', name='ams_can_bridge: pack',
                              message='MSL cell_voltage_max 4.31 beyond 4.25 (latched)',
                              values=[KeyValue(key=k, value=v) for k, v in values.items()])
    row = device_row('pack', BatteryState(voltage=48.0, current=-20.0), status)
    assert row.message == ('limits: charge 0 A, discharge 120 A; to empty 2 h 30 min, '
                           'to full n/a; MSL cell_voltage_max 4.31 beyond 4.25 (latched)')
    assert '  pack: limits: charge 0 A' in render(View(rows=[row]), unicode=False)
    # a device that is no pack keeps its line as it was
    plain = DiagnosticStatus(level=b'\x00', name='ams_can_bridge: bms16', message='OK')
    assert device_row('bms16', None, plain).message == ''


@pytest.mark.process
def test_the_pack_demo_shows_the_pack_row_its_limits_and_the_scenarios_event():
    """Show config/pack.yaml's pack in demo --pack, and the cell_over scenario's MSL."""
    result = subprocess.run([demo_executable(), '--pack', '--scenario', 'cell_over@3',
                             '--duration', '9', '--plain', '--interval', '0.5'],
                            capture_output=True, text=True, timeout=90, env=dict(os.environ))
    output = result.stdout + result.stderr
    assert result.returncode == 0, output[-3000:]
    assert 'Traceback' not in output, output[-3000:]
    shots = snapshots(result.stdout)
    packs = [rows_of_pack(shot) for shot in shots]
    assert all(set(rows) == {'bms16', 'evms3', 'pack'} for rows, _ in packs[-3:]), shots[-1]
    # inside every limit first: the pack's own limits at their full value
    ok = [line for rows, line in packs if rows.get('pack', [''])[-1] == 'OK']
    # (the very first report may come before the EVMS3's: limits 0 until both reported)
    assert any(line.startswith('pack: limits: charge 40 A, discharge 150 A') for line in ok), ok
    # then the scenario's cell past 4.20 V: MSL, latched, both limits 0
    rows, line = packs[-1]
    assert rows['pack'][1:3] == ['MSL', 'cell_voltag.'] and rows['pack'][-1] == 'ERROR'
    assert line.startswith('pack: limits: charge 0 A, discharge 0 A'), line
    assert 'pack scenario: cell_over from 3 s' in shots[-1]


def rows_of_pack(snapshot: str) -> tuple[dict[str, list[str]], str]:
    """Return the pair's and the pack's rows of one snapshot, and the pack's message line."""
    rows = {}
    line = ''
    for text in snapshot.splitlines():
        words = text.split()
        if len(words) > 2 and words[0] in ('bms16', 'evms3', 'pack') and words[-1] in (
                'OK', 'WARN', 'ERROR', 'STALE', 'n/a'):  # a table row, not a note
            rows[words[0]] = words
        if text.startswith('  pack: '):
            line = text.strip()
    return rows, line
