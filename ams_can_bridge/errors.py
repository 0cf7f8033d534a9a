# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The exceptions of ams_can_bridge, in one place (as python-can's ``can/exceptions.py``).

Every error the package raises on purpose derives from :class:`AmsCanBridgeError`, so a
script that embeds the bridge (or runs ``log2bag``) can catch the package's errors apart from
programming errors. The messages are written for the user: they name what to change.

The hierarchy::

    AmsCanBridgeError
     +-- ConfigError (also ValueError)      cannot start with these parameters
     |    +-- ParamError                    one parameter value that cannot be used
     |    +-- MsgDefsNotFound (FileNotFoundError) the installed msg_defs/ (DBC files) is missing
     +-- ProtocolError                      the protocol layer (protocols/)
     |    +-- MalformedFrameError           a received frame that is not a valid message
     |    +-- EncodeRangeError (ValueError) a value to send that the wire cannot carry
     |    +-- LayoutError (RuntimeError)    an installed DBC that no longer matches a codec
     |    +-- BadConfigBytes (ValueError)   setting bytes no device would send
     +-- CanSendError                       the bus is not available for sending
     +-- RefusedCommand                     a service call refused before any frame is sent
     +-- LogFileError                       a CAN log that cannot be read at all

Every module imports the errors from here (there is no second import place).

No rclpy and no python-can here: protocol code imports this module.
"""
from __future__ import annotations


class AmsCanBridgeError(Exception):
    """Base of every error ams_can_bridge raises on purpose."""


class ConfigError(AmsCanBridgeError, ValueError):
    """
    The bridge (or log2bag) cannot start with these parameters.

    Raised by the device set-up (``device_set.py``, ``parameters.py``) and the node's start;
    ``bridge`` and ``log2bag`` print the message and exit 2.
    """


class ParamError(ConfigError):
    """One parameter value that cannot be used (the message names it and what is allowed)."""


class MsgDefsNotFound(ConfigError, FileNotFoundError):
    """
    The installed msg_defs/ folder (the DBC files) cannot be found: an incomplete install.

    Raised by ``protocols.common.msg_defs_dir``; a FileNotFoundError too, for callers that
    treat a missing file alike.
    """


class ProtocolError(AmsCanBridgeError):
    """
    Base of every error the protocol layer (``protocols/``) raises on purpose.

    ``Device.handle`` catches it for every received frame: a bad frame is counted as
    malformed and dropped, never raised into the receive thread.
    """


class MalformedFrameError(ProtocolError):
    """
    A received frame that cannot be a valid message of its ID (count it, drop it).

    Raised by every ``protocols/*.decode`` (wrong length, reserved bits, a value outside the
    range the protocol documents) and by devices that check a frame against their config.
    """

    def __init__(self, arbitration_id: int, data: bytes, reason: str) -> None:
        self.arbitration_id = arbitration_id
        self.data = bytes(data)
        self.reason = reason
        super().__init__(
            f'malformed frame 0x{arbitration_id:X} [{self.data.hex(" ").upper()}]: {reason}')


class EncodeRangeError(ProtocolError, ValueError):
    """
    A value to send that the protocol cannot carry: out of range or off its step.

    Raised by the encoders in ``protocols/``; a command service answers it as a refused
    call, having sent nothing.
    """

    def __init__(self, field: str, value: object, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f'{field} = {value!r} cannot be sent: allowed {allowed}')


class LayoutError(ProtocolError, RuntimeError):
    """
    An installed DBC (msg_defs/) that no longer has the layout a codec was written for.

    Raised by ``protocols/layout.py`` when the first codec of a protocol is built: the bridge
    fails at start instead of decoding frames with the wrong bits.
    """


class BadConfigBytes(ProtocolError, ValueError):
    """
    Setting bytes (a whole configuration read back or received) that cannot be a configuration.

    Raised by the decoders of configuration payloads that have no single frame to blame
    (``protocols/bms16_std.decode_config``); the simulator ignores such a configuration.
    """


class CanSendError(AmsCanBridgeError):
    """
    A frame could not be sent: the bus is not connected, or the driver refused it.

    Raised by ``CanIo.send``; the command gate (``engine/gate.py``) turns it into a failed
    service answer (or a disarmed heartbeat) naming the bus and its state.
    """


class RefusedCommand(AmsCanBridgeError):
    """
    A service call that cannot go ahead; nothing was sent (the message says what to change).

    Raised by a device while the command pipeline (``engine/commands.py``) builds a command's
    frames: configuration unset, device stale, nothing to acknowledge. The service answers
    ``success: false`` with the message.
    """


class LogFileError(AmsCanBridgeError):
    """
    A CAN log that cannot be read at all: missing, unreadable, or a format python-can lacks.

    Raised by ``offline/log_frames.py`` (``log2bag`` prints it and exits 2) and by the
    replay interface (``can_io/replay.py``), whose receive thread reports it as the bus error.
    """


class CanIoError(AmsCanBridgeError):
    """The bus layer cannot do what was asked (a receive thread that would not end)."""
