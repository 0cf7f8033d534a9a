# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The log2bag golden: small logs of every device type and the digest of every message.

The logs (``fixtures/golden/*.log``) were written once from the simulators, with a silent
spell of some devices in the middle (their ``present: false`` repeats, the watch's early
/diagnostics); the digests (``fixtures/golden/digests.json``) are what log2bag wrote for
them before the speed work of issue 39 (at main 7b5d31f, before its merge): per scenario,
per message, the topic, the bag time and a SHA-256 prefix of the CDR bytes. Both are
committed: a digest taken from a pinned checkout would need the git history and a second
tree at test time, and simulator changes would move logs regenerated on the fly.
``test_log2bag_golden.py`` converts each log again and compares every message.

Regenerate (only when a message is meant to change, and say so in the commit):
``.venv/bin/python test/golden_bags.py --logs --digests`` (``--logs`` rewrites the logs too).
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
from pathlib import Path
import shutil
import sys
import tempfile
from typing import Any, Callable

import can

from ams_can_bridge import registry

FOLDER = Path(__file__).resolve().parent / 'fixtures' / 'golden'
DIGESTS = FOLDER / 'digests.json'
FIXTURES = Path(__file__).resolve().parent / 'fixtures'
START = 1_790_000_000.0
SECONDS = 7.0
SILENT = (2.0, 4.6)  # s from the start: the silent devices send nothing in this spell
TICK = 0.002


def _sim(kind: str, **options: Any) -> Any:
    variant = options.pop('variant', None)
    return registry.simulator_class(kind, variant)(**options)


# name -> (simulators: {instance: factory}, silent instances, parameters, files to copy)
SCENARIOS: dict[str, tuple[dict[str, Callable[[], Any]], tuple[str, ...], dict, tuple]] = {
    'car_mix': (
        {'ams': lambda: _sim('ams', name='ams', bank_count=5),
         'ivt_s': lambda: _sim('ivt_s', name='ivt_s'),
         'evms3': lambda: _sim('evms3', name='evms3', bms12_modules=8),
         'bms16': lambda: _sim('bms16', name='bms16', send_sma=True)},
        ('ivt_s', 'evms3'),
        {'devices': ['ams', 'ivt_s', 'evms3', 'bms16', 'sma'], 'ams.bank_count': 5,
         'evms3.bms12_modules': 8, 'evms3.config.pack_capacity_ah': 100.0,
         'diagnostics_period': 0.5}, ()),
    'bms16_std': (
        {'bms16': lambda: _sim('bms16', name='bms16', variant='standard')},
        ('bms16',), {'devices': ['bms16'], 'bms16.variant': 'standard'}, ()),
    'sma_pylontech': (
        {'sma': lambda: _sim('sma', name='sma', dialect='pylontech')},
        ('sma',), {'devices': ['sma']}, ()),
    'sma_victron': (
        {'sma': lambda: _sim('sma', name='sma', dialect='victron')},
        (), {'devices': ['sma']}, ()),
    'foxbms2': (
        {'dbc': lambda: _sim('dbc', name='dbc', profile='foxbms2')},
        ('dbc',), {'devices': ['dbc'], 'dbc.profile': 'foxbms2'}, ()),
    'orion_bms2': (
        {'dbc': lambda: _sim('dbc', name='dbc', profile='orion_bms2')},
        (), {'devices': ['dbc'], 'dbc.profile': 'orion_bms2'}, ()),
    'our_bms': (
        {'dbc': lambda: _sim('dbc', name='dbc', dbc_file=str(FIXTURES / 'our_bms.dbc'),
                             mapping_file=str(FIXTURES / 'our_bms_mapping.yaml'))},
        ('dbc',), {'devices': ['dbc'], 'dbc.dbc_file': 'our_bms.dbc',
                   'dbc.mapping_file': 'our_bms_mapping.yaml'},
        ('our_bms.dbc', 'our_bms_mapping.yaml')),
}


def write_log(name: str) -> int:
    """Write the scenario's log from its simulators; return the frames written."""
    factories, silent, _, _ = SCENARIOS[name]
    sims = {instance: factory() for instance, factory in factories.items()}
    count = 0
    with can.Logger(str(FOLDER / f'{name}.log')) as log:
        for step in range(int(round(SECONDS / TICK))):
            now = START + step * TICK
            quiet = SILENT[0] <= now - START < SILENT[1]
            for instance, sim in sims.items():
                for frame in sim.tick(now):
                    if quiet and instance in silent:
                        continue
                    log.on_message_received(can.Message(
                        timestamp=now, arbitration_id=frame.arbitration_id,
                        is_extended_id=frame.is_extended_id, data=frame.data))
                    count += 1
    return count


def bag_messages(bag: str) -> list[tuple[str, int, bytes]]:
    """Return (topic, bag time ns, CDR bytes) of every message, in the bag's order."""
    from rosbags.rosbag2 import Reader
    with Reader(bag) as reader:
        return [(connection.topic, t_ns, bytes(raw))
                for connection, t_ns, raw in reader.messages()]


def digest(messages: list[tuple[str, int, bytes]]) -> list[str]:
    """Return one line per message: topic, bag time ns, SHA-256 prefix of its bytes."""
    return [f'{topic} {t_ns} {hashlib.sha256(raw).hexdigest()[:16]}'
            for topic, t_ns, raw in messages]


def convert_in(work: Path, name: str, suffix: str = 'log') -> list[str]:
    """
    Convert the scenario's log (as ``suffix``) in folder work; return its digest lines.

    The log and the dbc files are given by relative names from work (the current directory
    is changed for the conversion): the hardware_id in /diagnostics carries the log's path.
    """
    from ams_can_bridge.offline.log2bag import convert
    _, _, parameters, files = SCENARIOS[name]
    for file in files:
        shutil.copy(FIXTURES / file, work / file)
    log = f'{name}.{suffix}'
    if suffix == 'log':
        shutil.copy(FOLDER / log, work / log)
    else:  # python-can's own writer, from the committed .log
        with can.LogReader(str(FOLDER / f'{name}.log')) as reader, \
                can.Logger(str(work / log)) as writer:
            for msg in reader:
                writer.on_message_received(msg)
    here = os.getcwd()
    os.chdir(work)
    try:
        convert(log, f'bag_{name}_{suffix}', parameters)
        return digest(bag_messages(str(work / f'bag_{name}_{suffix}')))
    finally:
        os.chdir(here)


GOLDEN_FORMATS = {'car_mix': ('log', 'blf')}  # every other scenario: .log only


def main() -> None:
    """Write the logs (--logs) and the digests (--digests) of every scenario."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--logs', action='store_true', help='write the logs again')
    parser.add_argument('--digests', action='store_true', help='write digests.json again')
    args = parser.parse_args()
    FOLDER.mkdir(parents=True, exist_ok=True)
    if args.logs:
        for name in SCENARIOS:
            print(name, write_log(name), 'frames')
    if args.digests:
        out: dict[str, list[str]] = {}
        for name in SCENARIOS:
            for suffix in GOLDEN_FORMATS.get(name, ('log',)):
                with tempfile.TemporaryDirectory() as work:
                    out[f'{name}.{suffix}'] = convert_in(Path(work), name, suffix)
                print(name, suffix, len(out[f'{name}.{suffix}']), 'messages')
        DIGESTS.write_text(json.dumps(out, indent=0) + '\n', encoding='utf-8')


if __name__ == '__main__':
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
