# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""protocols/settings.py: a device's configuration derived from its setting rows."""
import pytest

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import ConfigField
from ams_can_bridge.protocols.layout import Layout, LITTLE, Signal
from ams_can_bridge.protocols.settings import setting, Settings

# Two frames written by hand: a current in 10 A steps whose top end means "off", a flag,
# a voltage with an offset, an enum of shunt sizes, and a byte the module writes itself.
ROWS = Settings((
    Layout('A', 2, (
        setting('Warn', 0, 'warn_a', 10, 1210, 'A', 'warning', scale=10,
                sentinel=(1210, 'off')),
        setting('On', 1, 'on', 0, 1, '', 'enabled', bool))),
    Layout('B', 3, (
        setting('Cell', 0, 'cell_v', 1.5, 4.0, 'V', 'cell voltage', float, 0.01, 1.5),
        setting('Shunt', 1, 'shunt_a', 0, 500, 'A', 'shunt: 0, 100, 200 or 500 A',
                lookup=(0, 100, 200, 500)),
        Signal('Own', 16, 8, LITTLE)))))


def fail(why):
    return MalformedFrameError(1, b'', why)


def test_config_fields_come_from_the_rows():
    assert ROWS.fields() == (
        ConfigField('warn_a', int, 10, 1210, 10, 'A', 'warning (10..1210 A; 1210 = off)'),
        ConfigField('on', bool, description='enabled'),
        ConfigField('cell_v', float, 1.5, 4.0, 0.01, 'V', 'cell voltage (1.5..4 V)'),
        ConfigField('shunt_a', int, 0, 500, None, 'A', 'shunt: 0, 100, 200 or 500 A'))
    assert ROWS.sentinels() == {'warn_a': (1210, 'off')}
    plain = Settings(ROWS.layouts, ranged=False)
    assert plain.field('warn_a').description == 'warning'


def test_payload_and_decode_are_the_rows_both_ways():
    assert ROWS.payload(0, {'warn_a': 1210, 'on': True}) == bytes([121, 1])
    assert ROWS.payload(1, {'cell_v': 3.65, 'shunt_a': 200}, {'Own': 7}) == bytes([215, 2, 7])
    assert ROWS.decode(0, bytes([121, 1]), fail) == {'warn_a': 1210, 'on': True}
    assert ROWS.decode(1, bytes([215, 2, 7]), fail) == {'cell_v': 3.65, 'shunt_a': 200}
    assert ROWS.check('warn_a', 20.0) == 20 and type(ROWS.check('warn_a', 20.0)) is int


@pytest.mark.parametrize('name,value,allowed', [
    ('warn_a', 1215, '10..1210 A in steps of 10 A'), ('warn_a', 0, '10..1210 A'),
    ('cell_v', 3.655, '1.5..4 V in steps of 0.01 V'), ('on', 2, 'True/False (or 0/1)'),
    ('shunt_a', 300, 'shunt: 0, 100, 200 or 500 A'), ('shunt_a', True, 'shunt: 0'),
    ('nothing', 1, 'one of warn_a, on, cell_v, shunt_a'),
])
def test_encoding_refuses_off_range_and_off_step(name, value, allowed):
    with pytest.raises(EncodeRangeError) as info:
        ROWS.check(name, value)
    assert info.value.field == name and allowed in info.value.allowed


@pytest.mark.parametrize('k,data,reason', [
    (0, bytes([0, 1]), 'warn_a raw 0 outside 1..121'),
    (0, bytes([122, 1]), 'warn_a raw 122 outside 1..121'),
    (0, bytes([1, 2]), 'on raw 2, expected 0 or 1'),
    (1, bytes([251, 0, 0]), 'cell_v raw 251 outside 0..250'),
    (1, bytes([0, 4, 0]), 'shunt_a raw 4 outside 0..3'),
])
def test_decoding_a_raw_value_outside_the_row_is_malformed(k, data, reason):
    with pytest.raises(MalformedFrameError) as info:
        ROWS.decode(k, data, fail)
    assert info.value.reason == reason
    if k == 0:  # unchecked (a simulator clamps as the device does): the values as sent
        assert ROWS.decode(k, data)['warn_a'] == 10 * data[0]
