# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
A dbc device end to end: ``simulator --dbc --mapping`` and the installed ``bridge``, both on slcan.

Two processes, two fake USB-CAN adapters (ptys); this test is the wire between them: every
frame the simulator transmits is delivered to the bridge. The bridge publishes the team's
BMS as BatteryState (ROS units, cell arrays) and /diagnostics like any built-in device;
a typo in the mapping stops it with exit 2 naming the closest signal.
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
from sensor_msgs.msg import BatteryState

from dbc_fixtures import OUR_BMS_DBC, OUR_MAPPING, OUR_PARAMS, write_files
from executables import bridge_executable, package_executable
from slcan_peer import SlcanPeer


def simulator() -> str:
    return package_executable('simulator')


def _relay(source: SlcanPeer, target: SlcanPeer, stop: threading.Event) -> None:
    while not stop.is_set():
        for frame in source.received(clear=True):
            target.send(frame)
        stop.wait(0.01)


def _stop(proc: subprocess.Popen) -> str:
    proc.send_signal(signal.SIGINT)
    try:
        return proc.communicate(timeout=20)[0]
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.communicate(timeout=10)[0]


def test_simulated_dbc_bms_reaches_the_bridge_over_slcan(ros, tmp_path):  # noqa: F811
    node, executor = ros
    ns = f'dbc_slcan_{os.getpid()}'
    got: list[BatteryState] = []
    diags: list = []
    node.create_subscription(BatteryState, f'/{ns}/pack/battery_state', got.append, 50)
    node.create_subscription(
        DiagnosticArray, '/diagnostics',
        lambda m: diags.extend(s for s in m.status if s.name == f'{ns}/ams_can_bridge: pack'),
        50)
    sim_peer = SlcanPeer(symlink=tmp_path / 'ttySIM')
    bridge_peer = SlcanPeer(symlink=tmp_path / 'ttyBRIDGE')
    # the files beside the params file, named relatively; the bridge runs elsewhere
    car = tmp_path / 'car'
    car.mkdir()
    write_files(car)
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    params = car / 'bridge.yaml'
    params.write_text(f"""/**:
  ros__parameters:
    can: {{interface: slcan, channel: {bridge_peer.channel}, bitrate: 500000,
          options: [sleep_after_open=0]}}
    diagnostics_period: 0.5
    devices: [pack]
    pack:
      type: dbc
      dbc_file: our_bms.dbc
      mapping_file: pack_mapping.yaml
      stale_timeout: 1.0
""")
    sim = subprocess.Popen(
        [simulator(), '--interface', 'slcan', '--channel', sim_peer.channel, '--bitrate',
         '500000', '--option', 'sleep_after_open=0', '--dbc', OUR_PARAMS['dbc_file'],
         '--mapping', OUR_PARAMS['mapping_file']],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    bridge = subprocess.Popen(
        [bridge_executable(), '--ros-args', '-r', f'__ns:=/{ns}', '--params-file',
         str(params)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        env=dict(os.environ), cwd=elsewhere)
    stop = threading.Event()
    relay = threading.Thread(target=_relay, args=(sim_peer, bridge_peer, stop), daemon=True)
    try:
        sim_peer.wait_open(timeout=30)
        bridge_peer.wait_open(timeout=30)
        relay.start()

        def complete(m: BatteryState) -> bool:
            return m.present and len(m.cell_voltage) == 4 and all(
                math.isfinite(v) for v in (*m.cell_voltage, *m.cell_temperature, m.voltage,
                                           m.current, m.percentage, m.temperature))
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not (
                any(complete(m) for m in got) and any(s.level == b'\x00' for s in diags)):
            executor.spin_once(timeout_sec=0.1)
        last = [m for m in got if complete(m)]
        assert last, f'no complete BatteryState from the dbc device ({len(got)} messages)'
        m = last[-1]
        # the simulator's pack, in ROS units: cells around 3.5..4.1 V, SoC 0..1, degC
        assert all(3.0 < v < 4.3 for v in m.cell_voltage), list(m.cell_voltage)
        assert 0.0 <= m.percentage <= 1.0 and -60.0 < m.current < 60.0
        assert 10.0 < m.temperature < 45.0 and m.design_capacity == 20.0
        assert m.power_supply_status in (BatteryState.POWER_SUPPLY_STATUS_CHARGING,
                                         BatteryState.POWER_SUPPLY_STATUS_DISCHARGING)
        assert m.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_GOOD
        ok = [s for s in diags if s.level == b'\x00']
        assert ok, [(s.level, s.message) for s in diags[-3:]]
        values = {v.key: v.value for v in ok[-1].values}
        assert values['frames malformed'] == '0'
        assert 'BMS_PackValues.batteryVoltage [mV]' in values
        assert bridge.poll() is None and sim.poll() is None
    finally:
        stop.set()
        bridge_out = _stop(bridge)
        sim_out = _stop(sim)
        sim_peer.shutdown()
        bridge_peer.shutdown()
    assert bridge.returncode == 0 and 'Traceback' not in bridge_out, bridge_out
    assert sim.returncode == 0 and 'Traceback' not in sim_out, sim_out
    assert 'pack (dbc): 0x220, 0x222, 0x231, 0x235, 0x240, 0x250' in bridge_out, bridge_out
    # the start log: where the files were found (beside the params file), each formula
    assert f"DBC {car / 'our_bms.dbc'}, mapping {car / 'pack_mapping.yaml'}" in bridge_out
    assert 'percentage [0..1] = BMS_StateEstimation.packSoc [%] x 0.01' in bridge_out
    assert 'timeout BMS_CellVoltages (0x240): 1 s, stale_timeout' in bridge_out


def test_a_typo_in_the_mapping_stops_the_bridge_with_exit_2(tmp_path):
    # and a mapped message that is broken in the DBC (two signals on the same bits)
    files = write_files(tmp_path, OUR_BMS_DBC.replace('error : 8|8@1+', 'error : 2|8@1+'),
                        OUR_MAPPING.replace('packSoc', 'packSco').replace(
                            'primary: BMS_PackValues\n', ''))
    params = tmp_path / 'bad.yaml'
    params.write_text('/**:\n  ros__parameters:\n    devices: [pack]\n'
                      '    can: {interface: virtual, channel: dbc_typo}\n'
                      f"    pack: {{type: dbc, dbc_file: {files['dbc_file']}, "
                      f"mapping_file: {files['mapping_file']}}}\n")
    proc = subprocess.run([bridge_executable(), '--ros-args', '--params-file', str(params)],
                          capture_output=True, text=True, timeout=60, env=dict(os.environ))
    assert proc.returncode == 2 and 'Traceback' not in proc.stderr, proc.stderr
    assert "signal 'packSco' is not in message BMS_StateEstimation; closest: packSoc" \
        in proc.stderr, proc.stderr
    assert 'primary is not set' in proc.stderr  # every problem, not only the first
    assert 'message BMS_State is broken in the DBC (The signals error and mode are ' \
        'overlapping)' in proc.stderr


def test_simulator_refuses_a_bad_mapping_with_exit_2(tmp_path):
    files = write_files(tmp_path, mapping=OUR_MAPPING.replace('packSoc', 'packSco'))
    proc = subprocess.run([simulator(), '--dbc', files['dbc_file'], '--mapping',
                           files['mapping_file'], '--duration', '0.1'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and 'packSco' in proc.stderr, proc.stderr
    proc = subprocess.run([simulator(), '--dbc', files['dbc_file'], '--duration', '0.1'],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and '--dbc and --mapping go together' in proc.stderr
