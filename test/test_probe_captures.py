"""
probe on real public captures (test/fixtures/probe/README.md says where each comes from).

The expected results are written by hand from the captures: which device, at which IDs,
with which settings, which IDs nothing explains; and, through log2bag with the params
file probe wrote, the values the bridge then publishes, worked out byte by byte below.
"""
from __future__ import annotations

import json
from pathlib import Path
import re

import pytest

from ams_can_bridge.offline.converter import NODE_NAME
from ams_can_bridge.offline.log2bag import convert
from ams_can_bridge.offline.params_file import load_parameters
from ams_can_bridge.probe.main import main as probe_main
from test_log2bag import rosbags_read

FIXTURES = Path(__file__).parent / 'fixtures' / 'probe'
PRINTED = re.compile(r'Timestamp:\s+([\d.]+)\s+ID:\s+([0-9a-fA-F]+)\s+S\s+Rx\s+DL:\s+\d+\s+(.*)')


def foxbms_log(tmp_path: Path) -> Path:
    """Turn foxBMS's printed trace (python-can's message format) into a candump log."""
    lines = []
    for line in (FIXTURES / 'foxbms2' / 'test_log.txt').read_text().splitlines():
        stamp, can_id, data = PRINTED.fullmatch(line.strip()).groups()
        lines.append(f'({stamp}) can0 {int(can_id, 16):03X}#{data.replace(" ", "")}')
    path = tmp_path / 'foxbms2.log'
    path.write_text('\n'.join(lines) + '\n')
    return path


def probe(log: Path, tmp_path: Path, capsys) -> tuple[dict, dict, Path]:
    """Run probe --json --output; return its report, the parameters and the file."""
    out = tmp_path / 'probe.yaml'
    assert probe_main([str(log), '--json', '--output', str(out)]) == 0
    return json.loads(capsys.readouterr().out), load_parameters(str(out), NODE_NAME), out


def published(log: Path, params: dict, tmp_path: Path, topic: str) -> list:
    bag = tmp_path / 'bag'
    convert(str(log), str(bag), params)
    return [m for _, m in rosbags_read(str(bag))[topic]]


def test_foxbms2_trace_ivt_s_with_moved_results(tmp_path, capsys):
    log = foxbms_log(tmp_path)
    report, params, _ = probe(log, tmp_path, capsys)
    # I (MuxID 0) at 0x35C and U1 (MuxID 1) at 0x35D: an IVT-S at base 0x35C, big-endian
    # (0x35D 01 05 00 05 F0 34: 0x0005F034 = 389172 mV); T, W, Wh stay at 0x525, 0x526,
    # 0x528 (base 0x521): reported, not written (a second instance would need its own
    # command IDs, and the bridge reads one base per sensor).
    assert params['devices'] == ['ivt_s']
    assert params['ivt_s.base_id'] == 0x35C and params['ivt_s.byte_order'] == 'big'
    assert 'ivt_s.discharge_positive' not in params  # a check, commented out
    other = next(d for d in report['devices'] if not d['written'])
    assert other['type'] == 'ivt_s'
    assert [i['id'] for i in other['ids']] == [0x525, 0x526, 0x528]
    # foxBMS's own messages (0x220 BMS state, 0x221, cell voltages 0x240..0x251): no
    # protocol of the bridge, listed with their counts (0x220: 14 frames, every 100 ms)
    unplaced = {u['id']: u for u in report['unplaced']}
    assert set(unplaced) == {0x220, 0x221, *range(0x240, 0x252)}
    assert unplaced[0x220]['count'] == 14 and unplaced[0x220]['dlcs'] == [8]
    assert unplaced[0x221]['count'] == 1 and unplaced[0x221]['rate_hz'] is None

    states = [m for m in published(log, params, tmp_path, '/ivt_s/battery_state') if m.present]
    assert len(states) == 9  # one per 0x35C frame (the trace ends 0.5 s after the last)
    # first 0x35C: 00 05 00 00 03 3D = 829 mA, positive = discharge (default): -0.829 A;
    # U1 before it (0x35D 01 0A 00 05 F0 1A) = 389146 mV
    assert states[0].current == pytest.approx(-0.829, abs=1e-6)
    assert states[0].voltage == pytest.approx(389.146, abs=1e-3)


SMA = {  # capture -> (dialect, written settings, unplaced IDs, hand-decoded 0x356 and SoC)
    # 351 43 02 .. D0 01: charge 0x0243 = 57.9 V, discharge 0x01D0 = 46.4 V; 356 61 14 D3 FE
    # EB 00: 5217 = 52.17 V at 0.01 V (inside 46.4..57.9 V; 521.7 V is not), -301 x 0.1 A,
    # 235 x 0.1 degC; 355 SoC 60 %, high resolution 0x1784 = 60.20 % (agrees: used)
    'sma_victron_gx_seplos': ('victron', {'sma.inverter_keepalive': False,
                                          'sma.voltage_scale': 0.01}, set(),
                              dict(voltage=52.17, current=-30.1, temperature=23.5,
                                   percentage=0.602)),
    # 351 14 02 .. CC 01: 53.2 V, 46.0 V; 356 02 13 00 00 4A 01: 4866 = 48.66 V at 0.01 V,
    # 0 A, 330 x 0.1 degC; 355 1A 00: 26 %
    'sma_pylontech': ('pylontech', {'sma.voltage_scale': 0.01}, set(),
                      dict(voltage=48.66, current=0.0, temperature=33.0, percentage=0.26)),
    # 351 48 02 .. AE 01: 58.4 V, 43.0 V; 356 BE 14 F9 FF 8C 00: 5310 = 53.10 V at 0.01 V,
    # -7 x 0.1 A, 140 x 0.1 degC; 355 43 00: 67 %; 35F capacity 0x0069 = 105 Ah
    'sma_byd_lvs': ('victron', {'sma.inverter_keepalive': False, 'sma.voltage_scale': 0.01},
                    {0x35B, 0x360},
                    dict(voltage=53.10, current=-0.7, temperature=14.0, percentage=0.67,
                         capacity=105.0)),
    # 351 2E 02 .. B0 01: 55.8 V, 43.2 V; 356 0A 02 11 FF BE 00: 522 = 52.2 V at 0.1 V
    # (5.22 V at SMA's 0.01 V is far below 43.2 V), -239 x 0.1 A, 190 x 0.1 degC; 355 3E 00:
    # 62 %
    'sma_victron_discover': ('victron', {'sma.voltage_scale': 0.1}, {0x354},
                             dict(voltage=52.2, current=-23.9, temperature=19.0,
                                  percentage=0.62)),
}


@pytest.mark.parametrize('name', sorted(SMA))
def test_sma_family_captures(name, tmp_path, capsys):
    dialect, settings, unplaced, values = SMA[name]
    log = FIXTURES / f'{name}.log'
    report, params, out = probe(log, tmp_path, capsys)
    assert params['devices'] == ['sma']
    sma = report['devices'][0]
    assert sma['title'] == f'SMA-family battery ({dialect})' and sma['level'] == 'high'
    for key, value in settings.items():
        assert params[key] == value, key
    assert {u['id'] for u in report['unplaced']} == unplaced
    scale = next(s for s in sma['settings'] if s['key'] == 'voltage_scale')
    assert scale['decided'] and 'fits the 0x351 limits' in scale['why']
    assert f'      voltage_scale: {settings["sma.voltage_scale"]}\n' in out.read_text()
    states = published(log, params, tmp_path, '/sma/battery_state')
    assert len(states) == 3  # one per 0x356
    for field, value in values.items():
        assert getattr(states[-1], field) == pytest.approx(value, abs=1e-4), field
    # the file's fixed scale reads the first 0x356 already (auto waits for 0x351's evidence)
    assert all(s.voltage == pytest.approx(values['voltage'], abs=1e-4) for s in states)


def test_discover_capture_names_its_odd_frames(tmp_path, capsys):
    report, _, _ = probe(FIXTURES / 'sma_victron_discover.log', tmp_path, capsys)
    sma = report['devices'][0]
    # 0x373 with DLC 4 (the Victron extension needs 8) and the 0.1 V voltage
    assert any(n.startswith('0x373: DLC 4, expected 8') for n in sma['notes'])
    scale = next(s for s in sma['settings'] if s['key'] == 'voltage_scale')
    assert scale['why'] == ('52.2 V at 0.1 V/bit fits the 0x351 limits 43.2..55.8 V, 5.22 V '
                            'at 0.01 V/bit does not')
    assert ('voltage scale: 0x356 voltage 522 as sent (5.22 V at 0.01 V/bit, 52.2 V at 0.1 '
            'V/bit), 0x351 limits: charge 55.8 V, discharge 43.2 V, no readable cell voltages '
            '(0x373, binary 0x370)') in sma['evidence']
    assert any("BMS name 'Discover AES'" in e for e in sma['evidence'])
