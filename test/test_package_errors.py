# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""One exception hierarchy (errors.py) and the bus states as an Enum (bus_state.py)."""
import pytest

from ams_can_bridge import errors
from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.errors import (
    CanSendError, EncodeRangeError, LogFileError, MalformedFrameError, ProtocolError)
from ams_can_bridge.offline.log_frames import LogFrames
from ams_can_bridge.protocols.bms16 import Bms16Codec
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import Evms3Codec
from ams_can_bridge.reports import bus_report


def test_every_error_is_an_ams_can_bridge_error():
    assert (ProtocolError, MalformedFrameError, EncodeRangeError) == (
        errors.ProtocolError, errors.MalformedFrameError, errors.EncodeRangeError)
    for kind in (errors.ConfigError, errors.ParamError, ProtocolError, MalformedFrameError,
                 EncodeRangeError, CanSendError, errors.RefusedCommand, LogFileError):
        assert issubclass(kind, errors.AmsCanBridgeError), kind
    # the kinds users meet are distinct: a refused call is not a bad frame nor a bus fault
    assert not issubclass(errors.RefusedCommand, (ProtocolError, CanSendError))
    assert not issubclass(CanSendError, ProtocolError)


def test_raised_errors_are_caught_by_the_base():
    with pytest.raises(errors.AmsCanBridgeError, match='malformed frame 0x'):
        Evms3Codec().decode(0x12, b'\x01')
    with pytest.raises(errors.AmsCanBridgeError, match='base_id = 5000'):
        Bms16Codec(5000)
    with pytest.raises(errors.AmsCanBridgeError, match='does not exist'):
        LogFrames('/nonexistent/x.log')
    io = CanIo(BusConfig(interface='virtual', channel='test_package_errors'), lambda *a: None)
    with pytest.raises(errors.AmsCanBridgeError, match=r'not connected \(stopped\)'):
        io.send(Frame(1, b''))


def test_bus_state_text_is_what_logs_and_diagnostics_showed_before_the_enum():
    assert [str(s) for s in BusState] == [
        'connecting', 'connected', 'reconnecting', 'error', 'bus-off', 'error-passive',
        'replay finished', 'stopped']
    assert f'({BusState.BUS_OFF}: x)' == '(bus-off: x)' and '%s' % BusState.ERROR == 'error'
    status = BusStatus(state=BusState.BUS_OFF, reason='controller', frames_in=0, frames_out=0,
                       frames_dropped_tx=0, error_frames=0, reconnects=0, hardware_id='v:0')
    report = bus_report(status, 0, 'virtual')
    assert report.message == 'bus-off: controller' and report.values['state'] == 'bus-off'
    assert type(report.values['state']) is str
