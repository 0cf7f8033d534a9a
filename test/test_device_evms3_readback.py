# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Evms3Device.read_config and the read-back in diagnostics, without ROS (frames by hand)."""
import threading
import time

from ams_can_bridge.devices.evms3.device import Evms3Device
from ams_can_bridge.protocols.common import Frame
from helpers import Clock
from shared import (EVMS3_ANSWER as ANSWER, EVMS3_ANSWER_CELLS as CELLS,
                    EVMS3_GOLDEN_CONFIG as CONFIG)

STATUS_OK = bytes.fromhex('02 03 E8 0F A0 82 64 41')


def make(clock=None):
    return Evms3Device('evms3', {}, clock=clock or Clock(1000.0))


def answering(device, ids=tuple(ANSWER), sent=None):
    """Return a send() that records the frame and answers at once with the given IDs."""
    def send(frame):
        if sent is not None:
            sent.append(frame)
        for frame_id in ids:
            device.handle_frame(frame_id, ANSWER[frame_id], 1.0)
        return True, 'sent'
    return send


def test_read_config_sends_51_and_joins_the_answer():
    device = make()
    sent = []
    result = device.read_config(answering(device, sent=sent), timeout=1.0)
    assert sent == [Frame(51, b'', True)]
    assert result.ok and result.error == ''
    assert result.readback.config == CONFIG and result.readback.cells_per_module == CELLS


def test_answer_from_another_thread_after_the_send():
    device = make()

    def send(frame):
        def later():
            time.sleep(0.05)
            for frame_id, data in ANSWER.items():
                device.handle_frame(frame_id, data, 1.0)
        threading.Thread(target=later).start()
        return True, 'sent'
    assert device.read_config(send, timeout=5.0).ok


def test_partial_answer_fails_naming_the_missing_ids():
    device = make()
    start = time.monotonic()
    result = device.read_config(answering(device, ids=(52, 53, 55)), timeout=0.2)
    assert time.monotonic() - start >= 0.19  # waited the whole timeout
    assert not result.ok
    assert result.error == ('no complete answer within 0.2 s: incomplete: missing '
                            'ID 54 (config 3), ID 56 (cell numbers)')


def test_malformed_packet_is_named():
    device = make()

    def send(frame):
        device.handle_frame(52, ANSWER[52], 1.0)
        device.handle_frame(54, ANSWER[54][:7] + b'\x00', 1.0)  # sleep delay 0: not 1..6
        return True, 'sent'
    result = device.read_config(send, timeout=0.1)
    assert not result.ok
    assert 'missing ID 53 (config 2)' in result.error
    assert 'sleep_delay_min raw 0 outside 1..6' in result.error


def test_monitor_traffic_does_not_fail_a_read_in_flight():
    # EVMS_Monitor3.c: ID 31 DLC 2 while editing a gauge setting (TransmitGaugeState), ID 52
    # DLC 1 on entering setup and DLC 8 (its motor-controller settings) in TransmitSettings
    device = make()
    monitor = [(31, bytes.fromhex('02 50')), (31, bytes.fromhex('03 14')), (52, b'\x00'),
               (52, bytes.fromhex('64 96 50 3C 12 01 00 00'))]

    def send(frame):
        for frame_id, data in monitor:
            device.handle_frame(frame_id, data, 1.0)
        for frame_id, data in ANSWER.items():
            device.handle_frame(frame_id, data, 1.0)
        return True, 'sent'
    result = device.read_config(send, timeout=1.0)
    assert result.ok, result.error
    assert result.readback.config == CONFIG
    assert device.frames_malformed == 0


def test_sentinel_settings_show_off_and_never_in_the_diagnostics():
    # EVMS3 firmware: raw 121 current = off, 151 over-temperature = off, BMS min temp raw 0
    # and max temp raw 141 = off, CAN power-down delay 6 = never
    clock = Clock(1000.0)
    device = make(clock)
    device.handle_frame(30, STATUS_OK, 1.0)
    answer = {**ANSWER, 52: bytes.fromhex('14 14 C8 79 79 97 0B 32'),
              54: bytes.fromhex('05 00 8D 2C 9E FA 0A 06')}
    for frame_id, data in answer.items():
        device.handle_frame(frame_id, data, 1.0)
    values = device.diagnostic_report().values
    assert values['config warn_current_a (A)'] == 'off (1210)'
    assert values['config trip_current_a (A)'] == 'off (1210)'
    assert values['config temp_warning_c (degC)'] == 'off (151)'
    assert values['config bms_min_temp_c (degC)'] == 'off (-40)'
    assert values['config bms_max_temp_c (degC)'] == 'off (101)'
    assert values['config sleep_delay_min (min)'] == 'never (6)'
    assert values['config min_aux_voltage_v (V)'] == '11'


def test_refused_send_and_a_second_read_at_once():
    device = make()
    result = device.read_config(lambda frame: (False, 'commands are disabled'), 1.0)
    assert not result.ok and result.error == 'ID 51 was not sent: commands are disabled'
    release, sending = threading.Event(), threading.Event()
    first = {}

    def slow(frame):
        sending.set()
        release.wait(5.0)
        return True, 'sent'
    worker = threading.Thread(target=lambda: first.update(r=device.read_config(slow, 0.1)))
    worker.start()
    assert sending.wait(5.0)  # the first read is in its send: it waits
    second = device.read_config(answering(device), 1.0)
    release.set()
    worker.join(3.0)
    assert not second.ok and 'another read_config is waiting' in second.error
    assert not first['r'].ok  # nothing answered the first one


def test_listener_shows_a_complete_answer_in_the_diagnostics():
    clock = Clock(1000.0)
    device = make(clock)
    device.handle_frame(30, STATUS_OK, 1.0)
    for frame_id, data in ANSWER.items():  # a ZEVA Monitor asked, the EVMS answered
        device.handle_frame(frame_id, data, 1.0)
    clock.now += 3.0
    values = device.diagnostic_report().values
    assert values['config read back'] == '3.0 s ago (IDs 52..56)'
    assert values['config pack_capacity_ah (Ah)'] == '100'
    assert values['config bms_max_cell_v (V)'] == '3.65'
    assert values['config balance_mode'] == 'static'
    assert values['config enable_precharge'] == 'true'
    assert values['config cells_per_module'] == ', '.join(str(n) for n in CELLS)


def test_a_lone_52_is_not_shown_as_the_configuration():
    clock = Clock(1000.0)
    device = make(clock)
    device.handle_frame(30, STATUS_OK, 1.0)
    device.handle_frame(52, ANSWER[52], 1.0)  # a motor controller's settings frame, say
    values = device.diagnostic_report().values
    assert values['config read back'].startswith('incomplete: missing ID 53 (config 2)')
    assert not any(k.startswith('config pack') for k in values)
    for frame_id, data in ANSWER.items():
        if frame_id != 52:
            clock.now += 0.6  # five packets spread over 2.4 s: not one answer
            device.handle_frame(frame_id, data, 1.0)
    values = device.diagnostic_report().values
    assert values['config read back'] == 'incomplete: packets of different answers'
