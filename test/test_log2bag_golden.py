# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
log2bag's bags stay byte-identical: every message of every device type as before the speed work.

The speed work of issue 39 changes how messages are built and serialised and when the
periodic work runs; none of it may change a byte of what is written. Each scenario's log
(``fixtures/golden``: every device type, a silent spell of some devices) is converted and
every message (topic, bag time, SHA-256 of the CDR bytes) compared with the digest log2bag
gave before (``golden_bags.py`` says how both were made).
"""
import json

import pytest

from golden_bags import convert_in, DIGESTS, GOLDEN_FORMATS, SCENARIOS

GOLDEN = json.loads(DIGESTS.read_text(encoding='utf-8'))
CASES = [(name, suffix) for name in SCENARIOS for suffix in GOLDEN_FORMATS.get(name, ('log',))]


def test_the_golden_covers_every_device_type():
    kinds = set()
    for _, _, parameters, _ in SCENARIOS.values():
        for device in parameters['devices']:
            kinds.add((device, parameters.get(f'{device}.variant', '')))
    assert {kind for kind, _ in kinds} == {'ams', 'ivt_s', 'evms3', 'bms16', 'sma', 'dbc'}
    assert ('bms16', 'standard') in kinds


@pytest.mark.parametrize('name,suffix', CASES)
def test_every_message_is_byte_identical_to_the_golden(tmp_path, name, suffix):
    want = GOLDEN[f'{name}.{suffix}']
    got = convert_in(tmp_path, name, suffix)
    assert len(want) > 10
    for k, (mine, golden) in enumerate(zip(got, want)):
        assert mine == golden, f'{name}.{suffix}: message {k} differs from the golden'
    assert len(got) == len(want), f'{name}.{suffix}: {len(got)} messages, golden {len(want)}'
