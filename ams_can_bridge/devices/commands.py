# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What a device type declares about its commands: a table of rows, read by the one pipeline.

Each device class lists its commands in ``COMMANDS``, one :class:`Command` row each: the
service name, what it does in words (a refusal says "to <what>"), the request kind (Trigger
or SetBool), the device method the pipeline calls and the policy. What the pipeline does
with a row: doc/architecture.md, "Commands".

What each policy's method must return:

- :class:`Frames`: the method builds the call's frames (a ``Frame`` or a list; it raises
  ``RefusedCommand`` / ``EncodeRangeError`` to refuse, before anything is sent); the pipeline
  sends them in one batch, once or paced (``CONFIG_FRAME_GAP`` of the device after each).
- :class:`Exchange`: the method runs the call itself through a ``CallPort`` (devices/
  ports.py): commands and their answers (IVT-S 0x411 -> 0x511, EVMS3 51 -> 52..56), or a
  frame and what follows it (the charger's START and its repeat); it returns (ok, answer).
- :class:`Carried`: the method returns a :class:`Carry`: a command the heartbeat carries
  until the device confirms it (the AMS car commands).
- :class:`Local`: the method answers (ok, message) from the bridge's own state and sends
  nothing, so the transmit gate does not apply (the pack's ``clear_events``: a listen-only
  bridge must be able to clear what it reports; doc/packs.md).
"""
from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any, Protocol


class Request(enum.Enum):
    """The request a command service takes (std_srvs)."""

    TRIGGER = 'std_srvs/Trigger'
    SET_BOOL = 'std_srvs/SetBool'  # request.data reaches the method as its last argument


@dataclass(frozen=True)
class Frames:
    """The device builds the frames; the pipeline sends them in one batch, once or paced."""

    paced: bool = False  # a pause of the device's CONFIG_FRAME_GAP s after each frame
    say_gap: bool = False  # the answer names the pause ('(20 ms apart)')
    partial: str = ''  # what a sequence cut short leaves in the device (said in the answer)


@dataclass(frozen=True)
class Exchange:
    """The device runs the call through a ``CallPort`` and words its outcome."""

    # The pipeline waits for a (re)opening bus before the method runs, and the call's
    # frames then never wait: for a method that holds a lock of its own around its frames
    # (the charger's ordering lock), so no call waits for the bus holding it.
    bus_first: bool = False


@dataclass(frozen=True)
class Local:
    """The device answers from its own state and sends nothing (the pack's clear_events)."""


@dataclass(frozen=True)
class Carried:
    """The heartbeat carries the command until the device answers (the method: a Carry)."""


Policy = Frames | Exchange | Carried | Local
ONCE = Frames()
PACED = Frames(paced=True)
EXCHANGE = Exchange()
EXCHANGE_BUS_FIRST = Exchange(bus_first=True)
CARRIED = Carried()
LOCAL = Local()


@dataclass(frozen=True)
class CommandResult:
    """The answer of a command call."""

    success: bool
    message: str


class Carrier(Protocol):
    """What carries a command in its periodic frame (the AMS master)."""

    def command(self, command: Any, timeout: float,
                started: float | None = None) -> CommandResult:
        """Carry ``command`` and wait for its answer; ``timeout`` counts from ``started``."""


@dataclass(frozen=True)
class Carry:
    """A command for the heartbeat: who carries it, what, its name, the call's total bound."""

    carrier: Carrier
    command: Any
    name: str
    timeout: float  # s, the wait for the bus included


@dataclass(frozen=True)
class Command:
    """One command service of a device type (see the module docstring)."""

    service: str  # '<instance>/<service>'
    what: str  # 'reset the SoC': "commands_enabled is false: ... to reset the SoC"
    request: Request
    build: str  # the device method; looked up on the instance at each call
    policy: Policy
    args: tuple[Any, ...] = ()  # given to the method first (the AMS car command)
    what_false: str = ''  # SetBool: the words when request.data is false ('' = what)

    def words(self, data: bool | None = None) -> str:
        """Return what the call does, in words, for this request."""
        return self.what_false if data is False and self.what_false else self.what


TRIGGER = Request.TRIGGER
SET_BOOL = Request.SET_BOOL
