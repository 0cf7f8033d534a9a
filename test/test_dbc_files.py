# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Every msg_defs/*.dbc is a product of its own: it must open cleanly in teams' CAN tools.

Proved here with two independent readers: cantools (strict: overlapping or out-of-frame
signals fail) and canmatrix, both with every warning treated as a failure.
"""
import logging
import warnings

import cantools
import canmatrix.formats
import pytest

from ams_can_bridge.protocols.common import msg_defs_dir

EXPECTED = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma')
DBC_FILES = sorted(msg_defs_dir().glob('*.dbc'))


def test_one_dbc_file_per_protocol():
    assert sorted(p.stem for p in DBC_FILES) == sorted(EXPECTED)


@pytest.mark.parametrize('path', DBC_FILES, ids=lambda p: p.name)
def test_loads_in_cantools_strict_without_warnings(path):
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        db = cantools.database.load_file(str(path), strict=True)
    assert db.messages, f'{path.name} defines no message'
    for message in db.messages:
        assert message.signals or message.length == 0, f'{message.name} has no signals'
        for signal in message.signals:
            assert signal.comment or signal.choices or signal.unit is not None, (
                f'{path.name} {message.name}.{signal.name}: give it a unit, comment or values')


@pytest.mark.parametrize('path', DBC_FILES, ids=lambda p: p.name)
def test_loads_in_canmatrix_without_warnings(path, caplog):
    with caplog.at_level(logging.WARNING):
        matrices = canmatrix.formats.loadp(str(path))
    problems = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert not problems, f'canmatrix warned on {path.name}: {problems}'
    matrix = next(iter(matrices.values()))
    cantools_db = cantools.database.load_file(str(path))
    assert {(f.arbitration_id.id, f.arbitration_id.extended) for f in matrix.frames} == {
        (m.frame_id, m.is_extended_frame) for m in cantools_db.messages}
    for frame in matrix.frames:
        cantools_msg = cantools_db.get_message_by_frame_id(
            frame.arbitration_id.id, force_extended_id=frame.arbitration_id.extended)
        assert frame.arbitration_id.extended == cantools_msg.is_extended_frame, frame.name
        assert {s.name for s in frame.signals} == {s.name for s in cantools_msg.signals}
