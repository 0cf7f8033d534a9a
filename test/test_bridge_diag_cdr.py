# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ros/diag_cdr.py: what the bridge serializes itself reads back as rclpy's messages."""
import struct

from diagnostic_msgs.msg import DiagnosticArray
from hypothesis import given, settings, strategies as st
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import BatteryState
from std_msgs.msg import Float32MultiArray

from ams_can_bridge import cdr, registry
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.devices.base import BatteryReport, DiagnosticReport, Level
from ams_can_bridge.ros import convert, diag_cdr
from dbc_fixtures import OUR_PARAMS
from helpers import Clock

PARAMS = {'ams.bank_count': 2, 'evms3.bms12_modules': 3, 'pack.members': ['evms3', 'bms16'],
          **{f'dbc.{key}': value for key, value in OUR_PARAMS.items()}}
SIM_OPTIONS = {'ams': {'bank_count': 2}, 'evms3': {'bms12_modules': 3},
               'bms16': {'send_sma': True}, 'dbc': OUR_PARAMS}


def statuses_over_time():
    """Yield the (name, report) list of five devices, once per simulated second."""
    clock = Clock()
    devices = DeviceSet(list(registry.DEVICE_TYPES),
                        lambda name, spec: PARAMS.get(name, spec.default), clock=clock)
    sims = [registry.load(registry.SIMULATORS[n])(**SIM_OPTIONS.get(n, {}))
            for n in registry.DEVICE_TYPES if n not in ('sma', 'pack')]
    t = 0.0
    for second in range(4):
        for _ in range(20):
            for sim in sims:
                for f in sim.tick(t):
                    devices.handle_frame(f.arbitration_id, f.data, f.is_extended_id, t)
            t += 0.05
            clock.now += 0.05
        yield [(f'bridge: {name}', d.diagnostic_report()) for name, d in
               devices.devices.items()]


def wire(msg_or_bytes, kind=None) -> str:
    """Return what a subscriber reads, as text (NaN equals NaN there)."""
    if kind is None:
        kind, msg_or_bytes = type(msg_or_bytes), serialize_message(msg_or_bytes)
    return repr(deserialize_message(msg_or_bytes, kind))


def assert_reads_back(encoder, stamp, statuses, hardware_id='slcan:/dev/ttyACM0'):
    got = deserialize_message(encoder.encode(stamp, statuses, hardware_id), DiagnosticArray)
    assert got == diag_cdr.diagnostic_array(stamp, statuses, hardware_id)


def test_the_bridges_reports_second_after_second():
    encoder = diag_cdr.DiagnosticsEncoder()
    assert encoder.check()
    count = 0
    for statuses in statuses_over_time():
        assert_reads_back(encoder, 1_700_000_000.25 + count, statuses)
        count += sum(len(r.values) for _, r in statuses)
    assert count > 200  # the pairs' cache was used and updated, not only filled


@pytest.mark.parametrize('frame_text', ['', 'a', 'ab', 'abc', 'abcd', 'ünï'])
def test_every_alignment_and_a_changed_value(frame_text):
    encoder = diag_cdr.DiagnosticsEncoder()
    statuses = [(f'n{frame_text}', DiagnosticReport(Level.WARN, frame_text * 2, {
                    frame_text: frame_text, 'k' + frame_text: 'v', 'x': '1'})),
                ('', DiagnosticReport(Level.STALE, '', {})),
                (frame_text * 3, DiagnosticReport(Level.OK, 'm', {'a': frame_text}))]
    assert_reads_back(encoder, 5.5, statuses, frame_text)
    statuses[0][1].values['x'] = '22'  # the same key with a new value is encoded anew
    statuses[2][1].values['new key'] = 'z'
    assert_reads_back(encoder, float('nan'), statuses, frame_text)
    assert_reads_back(encoder, 5.5, [], frame_text)


def test_a_wrong_encoding_fails_the_start_check(monkeypatch):
    monkeypatch.setattr(cdr, '_pad4', lambda data: data)  # a key's padding left out
    assert not diag_cdr.DiagnosticsEncoder().check()


def test_telemetry_bytes_read_back_as_the_message_objects():
    # every device's BatteryState and arrays as the bridge publishes them, second after second
    assert diag_cdr.check_telemetry()
    clock = Clock()
    devices = DeviceSet(list(registry.DEVICE_TYPES),
                        lambda name, spec: PARAMS.get(name, spec.default), clock=clock)
    sims = [registry.load(registry.SIMULATORS[n])(**SIM_OPTIONS.get(n, {}))
            for n in registry.DEVICE_TYPES if n not in ('sma', 'pack')]
    t, checked = 0.0, 0
    for step in range(80):
        for sim in sims:
            for f in sim.tick(t):
                for device in devices.handle_frame(f.arbitration_id, f.data, f.is_extended_id,
                                                   t):
                    report = device.battery_report()
                    assert wire(diag_cdr.battery_state(report, 'link', 9.5), BatteryState) \
                        == wire(convert.battery_state(report, 'link', 9.5))
                    for rows, cols, data in device.extra_arrays().values():
                        assert wire(diag_cdr.multi_array(rows, cols, data), Float32MultiArray) \
                            == wire(convert.multi_array(rows, cols, data))
                    checked += 1
        t += 0.05
        clock.now += 0.05 if step != 40 else 30.0  # and once all stale
    assert checked > 100


@settings(max_examples=200, deadline=None)
@given(values=st.lists(st.floats(width=32) | st.floats(), min_size=7, max_size=7),
       ints=st.lists(st.integers(0, 255), min_size=3, max_size=3), present=st.booleans(),
       cells=st.lists(st.floats(), max_size=20), temps=st.lists(st.floats(), max_size=5),
       texts=st.lists(st.text(max_size=6).filter(lambda s: '\0' not in s), min_size=3,
                      max_size=3),
       stamp=st.floats(min_value=-1.0, max_value=4e9) | st.just(float('nan')))
def test_any_battery_report(values, ints, present, cells, temps, texts, stamp):
    report = BatteryReport(stamp, *values, *ints, present, cells, temps, texts[0], texts[1])
    assert wire(diag_cdr.battery_state(report, texts[2], 3.25), BatteryState) \
        == wire(convert.battery_state(report, texts[2], 3.25))


def test_a_wrong_telemetry_encoding_fails_the_start_check(monkeypatch):
    monkeypatch.setattr(cdr, 'CDR_LE', b'\0\0\0\0')  # big-endian claimed
    assert not diag_cdr.check_telemetry()


def test_a_wrong_float32_encoding_fails_the_start_check(monkeypatch):
    # a pack's four Float32 topics are published raw too: their bytes are checked at start
    monkeypatch.setattr(diag_cdr, 'float32',
                        lambda value: cdr.CDR_LE + struct.pack('>f', value))
    assert not diag_cdr.check_telemetry()
