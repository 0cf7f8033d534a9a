# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The probe command line: bad input, help, conflicts, unknown IDs, the user's DBC.

Bad input is one line and exit 2, the help needs no ROS, conflicts are settled and said, a
bus of unknown IDs still gets a params file the bridge accepts.
"""
from __future__ import annotations

import io
import os
from pathlib import Path
import subprocess
import sys

import pytest

from ams_can_bridge.offline.converter import NODE_NAME
from ams_can_bridge.offline.params_file import load_parameters
from ams_can_bridge.probe.evidence import Candidate
from ams_can_bridge.probe.main import main
from ams_can_bridge.probe.output import check_file
from ams_can_bridge.probe.recognise import settle
from dbc_fixtures import OUR_BMS_DBC_FILE, OUR_MAPPING_FILE
from executables import probe_executable
from shared import one_line_error


@pytest.mark.parametrize('case, contents, words', [
    ('missing', None, 'does not exist'),
    ('empty.log', '', 'holds no CAN frame (empty)'),
    ('text.log', 'these are\nnot CAN frames\n', 'no CAN frame read'),
    ('frames.xyz', '(1.0) can0 123#00\n', '.xyz'),
])
def test_an_unusable_log_is_one_line_and_exit_2(tmp_path, capsys, case, contents, words):
    path = tmp_path / case
    if contents is not None:
        path.write_text(contents)
    assert words in one_line_error(capsys, [str(path)])


def test_an_interface_that_does_not_open_is_one_line(tmp_path, capsys):
    line = one_line_error(capsys, ['--interface', 'slcan', '--channel', str(tmp_path / 'ttyX'),
                                   '--bitrate', '500000', '--duration', '0.5'])
    assert f'cannot open slcan:{tmp_path / "ttyX"} at 500000 bit/s' in line


def test_a_bus_without_a_frame_is_one_line(capsys):
    line = one_line_error(capsys, ['--interface', 'virtual', '--channel',
                                   f'probe_empty_{os.getpid()}', '--duration', '0.3'])
    assert line.startswith('probe: no frame in 0.3 s on virtual:')


def test_auto_rate_needs_a_silent_listener(capsys):
    line = one_line_error(capsys, ['--interface', 'virtual', '--channel', 'x', '--bitrate',
                                   'auto'])
    assert 'listen-only' in line and '--bitrate 500000' in line


def test_a_dbc_that_does_not_load_is_one_line(tmp_path, capsys):
    log = tmp_path / 'bus.log'
    log.write_text('(1.0) can0 123#00\n')
    line = one_line_error(capsys, [str(log), '--dbc', str(tmp_path / 'none.dbc'),
                                   '--mapping', str(OUR_MAPPING_FILE)])
    assert 'none.dbc' in line and 'not found' in line


def test_an_output_folder_that_does_not_exist_is_one_line(tmp_path, capsys):
    log = tmp_path / 'bus.log'
    log.write_text('(1.0) can0 123#00\n')
    line = one_line_error(capsys, [str(log), '--output', str(tmp_path / 'no' / 'p.yaml')])
    assert 'does not exist' in line
    assert not (tmp_path / 'no').exists()


@pytest.mark.parametrize('argv, words', [
    (['a.log', '--interface', 'slcan', '--channel', 'x'], 'not both'),
    ([], 'give a LOG'),
    (['--interface', 'slcan'], 'both --interface and --channel'),
    (['a.log', '--dbc', 'x.dbc'], '1 --dbc and 0 --mapping'),
    (['a.log', '--bitrate', 'fast'], 'a rate in bit/s'),
    (['a.log', '--duration', '0'], 'more than 0'),
])
def test_a_command_line_mistake_exits_2(capsys, argv, words):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert words in capsys.readouterr().err


def test_installed_probe_answers_help():
    result = subprocess.run([probe_executable(), '--help'], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0 and 'usage: probe' in result.stdout
    assert '--bitrate' in result.stdout and 'never sends' in result.stdout


def cand(title: str, confidence: float, *ids: int, user: bool = False) -> Candidate:
    return Candidate('dbc', title, title, confidence, frozenset((i, False) for i in ids),
                     user_given=user)


def test_settle_keeps_one_candidate_per_id_and_says_which():
    wide = cand('wide', 0.6, 1, 2, 3)
    narrow = cand('narrow', 0.9, 2, 3)   # more confident, but explains less
    mine = cand('mine', 0.7, 7, 8, user=True)
    builtin = cand('builtin', 0.7, 8, 9)
    weak = cand('weak', 0.4, 1)
    kept, conflicts = settle([narrow, builtin, wide, mine, weak])
    assert {c.title for c in kept} == {'wide', 'mine'}
    said = {(c.kept.title, c.dropped.title) for c in conflicts}
    # the wider one explains all the narrow one does; on a tie the user's DBC wins; a weak
    # match set aside is not reported
    assert said == {('wide', 'narrow'), ('mine', 'builtin')}
    text = next(c for c in conflicts if c.dropped is narrow).text()
    assert 'narrow (high, 0.90) and wide (medium, 0.60) both explain 0x2-0x3: kept wide' == text


def test_unknown_ids_give_a_report_and_a_file_the_bridge_accepts(tmp_path, capsys):
    log = tmp_path / 'bus.log'
    log.write_text(''.join(f'({1.0 + k * 0.1:.6f}) can0 {0x123 + k % 2:03X}#0102{k % 256:02X}\n'
                           for k in range(40)))
    out = tmp_path / 'p.yaml'
    assert main([str(log), '--output', str(out)]) == 0
    report = capsys.readouterr().out
    assert 'devices found: 0' in report
    assert '0x123' in report and '0x124' in report and '10 Hz' not in report  # 5 Hz each
    check_file(str(out))
    assert load_parameters(str(out), NODE_NAME)['devices'] == []


def test_the_users_dbc_and_a_builtin_device_on_one_bus(tmp_path, capsys):
    """Our BMS from its DBC beside an SMA battery: both found, the params file reads both."""
    from ams_can_bridge.sim.dbc import DbcSimulator
    from ams_can_bridge.sim.recording import write_log
    from ams_can_bridge.sim.sma import SmaSimulator
    log = tmp_path / 'bus.log'
    write_log(str(log), [DbcSimulator('pack', str(OUR_BMS_DBC_FILE), str(OUR_MAPPING_FILE)),
                         SmaSimulator('sma')], 5.0)
    out = tmp_path / 'p.yaml'
    assert main([str(log), '--dbc', str(OUR_BMS_DBC_FILE), '--mapping', str(OUR_MAPPING_FILE),
                 '--output', str(out)]) == 0
    report = capsys.readouterr().out
    params = load_parameters(str(out), NODE_NAME)
    name = 'our_bms_mapping'
    assert params['devices'] == ['sma', name], report
    assert params[f'{name}.type'] == 'dbc'
    assert Path(params[f'{name}.dbc_file']) == OUR_BMS_DBC_FILE
    assert Path(params[f'{name}.mapping_file']) == OUR_MAPPING_FILE
    assert 'IDs no device explains' not in report
    check_file(str(out))


def test_an_ams_and_the_ams_dbc_are_a_conflict(tmp_path, capsys):
    """Two candidates for the AMS frames (the built-in device and its DBC): one is kept."""
    from ams_can_bridge.sim.ams import AmsSimulator
    from ams_can_bridge.sim.recording import write_log
    log = tmp_path / 'bus.log'
    write_log(str(log), [AmsSimulator('ams', bank_count=2)], 4.0)
    assert main([str(log), '--dbc', 'msg_defs/ams.dbc', '--mapping',
                 'config/ams_dbc_mapping.yaml']) == 0
    report = capsys.readouterr().out
    conflicts = report.split('conflicts (two candidates for the same IDs):')[1]
    assert 'AMS at base 0x300' in conflicts and 'ams.dbc' in conflicts
    assert report.count(', written') == 1


def test_probe_as_a_module_runs_without_ros():
    result = subprocess.run([sys.executable, '-m', 'ams_can_bridge.probe.main', '--help'],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and 'usage: probe' in result.stdout


class Terminal(io.StringIO):
    """A stream that says it is a terminal: probe draws its progress line there."""

    def isatty(self) -> bool:
        return True


def test_listening_draws_a_progress_line_on_a_terminal():
    import can

    from ams_can_bridge.probe.sources import Listener, open_bus
    channel = f'probe_progress_{os.getpid()}'
    sender = can.Bus(interface='virtual', channel=channel)
    bus = open_bus('virtual', channel, 0, {}, listen_only=False)
    screen = Terminal()
    try:
        for k in range(5):
            sender.send(can.Message(arbitration_id=0x123, data=bytes([k])))
        assert Listener(screen).listen(bus, 0.5, 'listening') == 5
    finally:
        bus.close()
        sender.shutdown()
    drawn = screen.getvalue()
    assert '\rprobe: listening: ' in drawn and 'of 0.5 s, 5 frames, 1 IDs' in drawn
    assert not hasattr(bus, 'send')  # probe's bus cannot send


def test_a_frame_a_recogniser_cannot_read_stops_only_that_recogniser():
    from ams_can_bridge.errors import MalformedFrameError
    from ams_can_bridge.probe import ivt_s, sma
    from ams_can_bridge.probe.recognise import recognise
    from ams_can_bridge.probe.report import as_data, text as as_text
    from ams_can_bridge.probe.traffic import Traffic

    def fussy(traffic, found):  # a recogniser meeting a frame it did not expect
        raise MalformedFrameError(0x525, bytes.fromhex('0400000000D2'), 'T: out of range')

    traffic = Traffic()
    for k in range(20):  # an IVT-S current result at 0x521, 20 ms apart: I = 1.000 A
        traffic.add(0x521, False, bytes([0, k % 16]) + (1000).to_bytes(4, 'big'), k * 0.02)
    findings = recognise(traffic, (fussy, ivt_s.recognise, sma.recognise))
    assert [c.type for c in findings.devices] == ['ivt_s']  # the others still ran
    assert findings.failures == ['test_probe_cli: malformed frame 0x525 [04 00 00 00 00 D2]: '
                                 'T: out of range']
    text = as_text(findings, traffic, 'bus.log')
    assert 'recognisers a frame stopped' in text and 'T: out of range' in text
    assert as_data(findings, traffic, 'bus.log')['failures'] == findings.failures
