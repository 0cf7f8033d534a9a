# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""protocols/layout.py: generated decoders and encoders equal cantools; one validator."""
import contextlib
import enum
import importlib

import cantools
import pytest
from hypothesis import given, settings, strategies as st

from ams_can_bridge.errors import EncodeRangeError, LayoutError
from ams_can_bridge.protocols.ams import AmsCodec
from ams_can_bridge.protocols.bms16 import Bms16Codec
from ams_can_bridge.protocols.common import load_dbc, msg_defs_dir
from ams_can_bridge.protocols.evms3 import Evms3Codec
from ams_can_bridge.protocols.ivt_s import IvtSCodec
from ams_can_bridge.protocols.layout import (
    BadValue, check_value, compile_function, Layout, LITTLE, Signal, tolerance)
from ams_can_bridge.protocols.sma import SmaCodec

CHECKED_MODULES = ('ams', 'bms16', 'evms3', 'ivt_s', 'sma')  # each has check_dbc()
MESSAGES = [(name, m) for name in ('ams', 'bms16', 'evms3', 'ivt_s', 'sma')
            for m in load_dbc(name).messages
            if m.length and not m.is_multiplexed() and not any(s.is_float for s in m.signals)]


@settings(max_examples=400, deadline=None)
@given(which=st.sampled_from(range(len(MESSAGES))), data=st.binary(min_size=8, max_size=8))
def test_generated_code_equals_cantools_on_every_dbc(which, data):
    _, message = MESSAGES[which]
    layout = Layout.from_dbc(message)
    data = data[:message.length]
    want = message.decode(data, decode_choices=False)
    got = layout.decoder()(data)
    assert got == tuple(want[s.name] for s in message.signals)
    try:
        encoded = layout.encoder()(*got)
    except EncodeRangeError:  # a value outside the DBC's [min|max]: refused, as cantools
        with pytest.raises(cantools.database.EncodeError):
            message.encode(want, strict=True)
        return
    assert encoded == message.encode(want, strict=False)


@contextlib.contextmanager
def dbc_changed(monkeypatch, module: str, dbc: str, old: str, new: str):
    """Give protocols.<module> msg_defs/<dbc>.dbc with old replaced by new; yield the module."""
    protocol = importlib.import_module(f'ams_can_bridge.protocols.{module}')
    text = (msg_defs_dir() / f'{dbc}.dbc').read_text()
    assert old in text
    changed = cantools.database.load_string(text.replace(old, new, 1), strict=True)
    monkeypatch.setattr(protocol, 'load_dbc', lambda name: changed)
    protocol.check_dbc.cache_clear()
    try:
        yield protocol
    finally:
        protocol.check_dbc.cache_clear()  # the next codec checks the real DBC again


@pytest.mark.parametrize('module, old, new, message', [
    ('evms3', 'SG_ AuxVoltage : 40|8@1+ (0.1,0)', 'SG_ AuxVoltage : 40|8@1+ (0.2,0)',
     'EVMS3_Status does not match the EVMS3 codec'),
    ('ams', 'SG_ SOC : 39|8@0+ (1,0) [0|100]', 'SG_ SOC : 39|8@0+ (2,0) [0|200]',
     'AMS_Status does not match the AMS codec layout'),
])
def test_the_check_refuses_a_dbc_with_other_bits(monkeypatch, module, old, new, message):
    with dbc_changed(monkeypatch, module, module, old, new) as protocol:
        with pytest.raises(LayoutError, match=message):
            protocol.check_dbc()


@pytest.mark.parametrize('module', CHECKED_MODULES)
def test_every_shipped_table_equals_its_shipped_dbc(module):
    # The tables are checked against msg_defs/ here, at test time, not at every start
    # (cantools parsing the five DBCs was 0.13 s of each start; bench/README.md, third pass).
    protocol = importlib.import_module(f'ams_can_bridge.protocols.{module}')
    protocol.check_dbc.cache_clear()
    protocol.check_dbc()


def test_building_the_codecs_reads_no_dbc(monkeypatch):
    def refuse(name):
        raise AssertionError(f'a codec read msg_defs/{name}.dbc at start')
    for module in CHECKED_MODULES:
        protocol = importlib.import_module(f'ams_can_bridge.protocols.{module}')
        monkeypatch.setattr(protocol, 'load_dbc', refuse)
        protocol.check_dbc.cache_clear()
    try:
        codecs = [AmsCodec(), Evms3Codec(), Bms16Codec(), IvtSCodec(), SmaCodec()]
        assert all(codec.arbitration_ids for codec in codecs)
    finally:
        for module in CHECKED_MODULES:
            importlib.import_module(f'ams_can_bridge.protocols.{module}').check_dbc.cache_clear()


@pytest.mark.parametrize('value,kwargs,allowed', [
    (5.12, dict(low=0, high=5.1, step=0.02, unit='V'), '0..5.1 V in steps of 0.02 V'),
    (3.61, dict(low=0, high=5.1, step=0.02, unit='V'), 'in steps of 0.02 V'),
    (2.5, dict(low=1, high=5, integer=True), '1..5, a whole number'),
    (True, dict(low=0, high=5), 'a number 0..5'),
    ('3', dict(low=0, high=5), 'a number 0..5'),
    (float('nan'), dict(low=0, high=5), '0..5'),
])
def test_check_value_refuses(value, kwargs, allowed):
    with pytest.raises(EncodeRangeError) as info:
        check_value('x', value, **kwargs)
    assert allowed in info.value.allowed and info.value.field == 'x'


def test_check_value_takes_float_noise_at_the_ends_and_whole_floats():
    assert check_value('v', 255 * 0.02, 0, 5.1, 0.02) == 5.1
    assert check_value('n', 3.0, 0, 5, integer=True) == 3
    assert isinstance(check_value('n', 3.0, 0, 5, integer=True), int)


def test_tolerance_is_the_float_noise_check_value_forgives():
    assert tolerance(0, 5.1, 0.02) == pytest.approx(2e-11)  # a billionth of the step
    assert tolerance(-400, 100) == pytest.approx(4e-7)  # of the larger end without one
    assert tolerance(0, 0.5) == pytest.approx(1e-9)  # at least a billionth of 1
    assert check_value('v', 100 + 3e-7, -400, 100) == 100
    with pytest.raises(EncodeRangeError):
        check_value('v', 100 + 5e-7, -400, 100)


def test_value_expression_compiled_beside_the_table_equals_its_decoder():
    layout = Layout('M', 2, (Signal('a', 0, 12, LITTLE, scale=0.5, offset=-10),
                             Signal('f', 15, 1, LITTLE, flag=True)))
    body = ', '.join(layout.value_expression(s) for s in layout.signals)
    both = compile_function(f'def f(data):\n    return ({body},)\n', 'M', 'f')
    for data in (b'\x00\x00', b'\xff\x8f', b'\x34\x02', b'\x01\x80'):
        assert both(data) == layout.decoder()(data)
    assert both(b'\x34\x82') == (0x234 * 0.5 - 10, True)


@pytest.mark.parametrize('module,dbc,old,new,message', [
    ('bms16', 'bms16', 'SG_ Voltage : 16|16@1+ (0.1,0)', 'SG_ Voltage : 16|16@1+ (0.2,0)',
     'BMS16_Status'),
    ('sma', 'sma', 'SG_ SoH : 16|16@1+ (1,0)', 'SG_ SoH : 16|8@1+ (1,0)', 'SMA_SoC'),
    ('sma', 'sma', 'SG_ ModuleCount : 32|8@1+', 'SG_ ModuleCount : 40|8@1+',
     'Pylontech_AlarmsWarnings'),
    ('evms3', 'evms3', 'SG_ BmsMinVoltage : 40|8@1+ (0.01,1.5)',
     'SG_ BmsMinVoltage : 40|8@1+ (0.01,1.6)', 'EVMS3_Config2'),
    ('evms3', 'evms3', 'SG_ Module15Cells : 60|4@1+', 'SG_ Module15Cells : 60|3@1+',
     'EVMS3_BmsCellNumbers'),
    ('evms3', 'evms3', 'SG_ CurrentLimit : 23|16@0+ (0.1,0)',
     'SG_ CurrentLimit : 23|16@0+ (0.2,0)', 'TC_Charger1_Command'),
    ('ivt_s', 'ivt_s', 'SG_ IVT_MsgCount_Result_W : 11|4@0+',
     'SG_ IVT_MsgCount_Result_W : 11|3@0+', 'IVT_Msg_Result_W'),
])
def test_each_codec_checks_its_whole_table_against_its_dbc(monkeypatch, module, dbc, old, new,
                                                           message):
    with dbc_changed(monkeypatch, module, dbc, old, new) as protocol:
        with pytest.raises(LayoutError, match=message):
            protocol.check_dbc()


# --- a row's check: the rules of a protocol beside its bits (decode refuses, encode too) -------
class _Mode(enum.IntEnum):
    OFF = 1
    ON = 2


CHECKED = Layout('Checked', 4, (
    Signal('Mode', 0, 4, LITTLE, field='mode', lookup=(None, *_Mode),
           check='unknown mode {value} (known {low}..{high})'),
    Signal('Count', 4, 4, LITTLE, low=1, high=5, field='count',
           check='count {value} (allowed {low:g}..{high:g})'),
    Signal('Temp', 8, 16, LITTLE, True, 0.1, low=-273.2, field='temp', invalid=-0x8000,
           check='{value:g} degC is below {low:g} degC'),
    Signal('Cell1', 24, 4, LITTLE), Signal('Cell2', 28, 4, LITTLE)), divide=True)


def test_a_checked_row_decodes_what_the_protocol_allows():
    decode = CHECKED.decoder(tail=2)
    assert decode(bytes([0x31, 0x00, 0x80, 0x21])) == (_Mode.OFF, 3, None, (1, 2))
    assert decode(bytes([0x52, 0x55, 0xF5, 0x00])) == (_Mode.ON, 5, -273.1, (0, 0))


@pytest.mark.parametrize('data,message', [
    ('30 00 00 00', 'unknown mode 0 (known 1..2)'),  # no member for 0
    ('3F 00 00 00', 'unknown mode 15 (known 1..2)'),  # past the lookup's end
    ('01 00 00 00', 'count 0 (allowed 1..5)'),
    ('61 00 00 00', 'count 6 (allowed 1..5)'),
    ('11 53 F5 00', '-273.3 degC is below -273.2 degC'),  # on the raw integer: -2733
])
def test_a_checked_row_refuses_what_the_protocol_does_not_allow(data, message):
    with pytest.raises(BadValue) as info:
        CHECKED.decoder()(bytes.fromhex(data))
    assert str(info.value) == message


def test_a_checked_lookup_encodes_only_its_members():
    encode = CHECKED.encoder()
    assert encode(_Mode.ON, 1, None, 0, 0) == bytes([0x12, 0x00, 0x80, 0x00])
    assert encode(1, 1, 0, 0, 0) == bytes([0x11, 0, 0, 0])  # the member's int value
    for value in (3, 0, True, 1.0, 'ON'):
        with pytest.raises(EncodeRangeError) as info:
            encode(value, 1, 0, 0, 0)
        assert info.value.field == 'mode' and info.value.allowed == 'a _Mode value (OFF=1, ON=2)'
    with pytest.raises(EncodeRangeError, match='count'):
        encode(_Mode.ON, 6, 0, 0, 0)


def test_setting_columns_change_no_generated_code():
    # description, kind and sentinel (the columns a configuration row adds) are for
    # protocols/settings.py only: the same bits decode and encode exactly as without them.
    from dataclasses import replace
    from ams_can_bridge.protocols.layout import LITTLE, Signal
    plain = Signal('Warn', 0, 8, LITTLE, scale=10, low=10, high=1210, unit='A', field='warn')
    rich = replace(plain, description='warning', kind=int, sentinel=(1210, 'off'))
    assert (plain.description, plain.kind, plain.sentinel) == ('', None, None)
    a, b = Layout('X', 1, (plain,)), Layout('X', 1, (rich,))
    for raw in (1, 121, 255):
        assert a.decoder()(bytes([raw])) == b.decoder()(bytes([raw]))
    assert a.encoder()(1210) == b.encoder()(1210) == bytes([121])
    with pytest.raises(EncodeRangeError):
        b.encoder()(1215)  # off the step: still refused
