"""
The one command pipeline: a command service call, from its row to the bus, without ROS.

Every command of every device passes ``Pipeline.call`` (the rows: devices/commands.py):

1. the call is named to the gate (its command log lines name ``<instance>/<service>``);
2. while commands are disabled it is refused, here and only here, naming the parameters,
   and nothing is sent (a ``Local`` row sends nothing at all: it answers from the bridge's
   own state, commands enabled or not);
3. the device's method runs as the row's policy says: ``Frames`` (the frames are built, a
   deliberate refusal, ``RefusedCommand`` or ``EncodeRangeError``, becomes the answer and
   nothing is sent; the bus is waited for once, outside the batch; the frames go out in one
   ``gate.batch()``, paced or not; a frame the gate refuses ends the call, and the answer
   names what was sent and what not), ``Exchange`` (the device runs the call through a
   ``CallPort``: each frame through the gate, waiting for the bus), ``Carried`` (the bus is
   waited for within the command's own timeout, then the heartbeat carries it);
4. anything else the device raises is a bug: logged with its traceback (ERROR) and
   answered as an internal error, never as a refusal;
5. the answer is logged (INFO when it succeeded, WARN when not).
"""
from __future__ import annotations

import time
import traceback
from functools import partial
from typing import Any, Callable, Iterable, Mapping, Protocol

from ams_can_bridge.devices.base import Device
from ams_can_bridge.devices.commands import Carried, Carry, Command, Exchange, Frames, Local
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.errors import EncodeRangeError, RefusedCommand
from ams_can_bridge.protocols.common import Frame

SetConfig = Callable[[str, Mapping[str, Any]], tuple[bool, str]]  # (instance, {key: value})


class Log(Protocol):
    """The node's logger (rclpy's, or a stdlib logger in a test)."""

    def info(self, message: str, /) -> object:
        """Log at INFO."""

    def warning(self, message: str, /) -> object:
        """Log at WARN."""

    def error(self, message: str, /) -> object:
        """Log at ERROR."""


def frame_text(frame: Frame) -> str:
    """Describe a frame as 'ID 32 (0x20) [01 02 ..]'."""
    data = frame.data.hex(' ').upper() or 'no data'
    return f'ID {frame.arbitration_id} (0x{frame.arbitration_id:X}) [{data}]'


def no_config(name: str, values: Mapping[str, Any]) -> tuple[bool, str]:
    """Refuse a parameter set: no parameters to set here (a pipeline without a node)."""
    return False, 'this bridge has no parameters to set'


class Pipeline:
    """Refuse, build, wait, send, answer: every command of every device (module docstring)."""

    def __init__(self, gate: CommandGate, log: Log, *, set_config: SetConfig = no_config,
                 bus_ready: Callable[[str], object] = lambda name: None,
                 sleep: Callable[[float], object] = time.sleep) -> None:
        """
        Send through ``gate``; ``set_config`` sets an instance's parameters all or none.

        ``bus_ready(instance)`` is told when a call of that instance has waited for the bus
        and found it connected (its periodic senders start now, not when their own wait
        wakes up); ``sleep`` paces a paced row.
        """
        self.gate = gate
        self._log = log
        self._set_config = set_config
        self._bus_ready = bus_ready
        self._sleep = sleep

    def call(self, name: str, device: Device, row: Command, data: bool | None = None,
             source: str | None = None) -> tuple[bool, str]:
        """Run one call of ``row`` on instance ``name``: (success, answer); never raises."""
        source = source or f'{name}/{row.service}'
        try:
            with self.gate.calling(source):
                ok, message = self._run(name, device, row, data)
        except Exception as exc:  # a bug, not a refusal: say so, keep the traceback
            self._log.error(f'{source}: internal error:\n' + traceback.format_exc())
            ok, message = False, (f'{source}: internal error: {type(exc).__name__}: {exc}; '
                                  'see the log')
        answer = f'{source}: answered success={ok}: {message}'
        if ok:
            self._log.info(answer)
        else:
            self._log.warning(answer)
        return ok, message

    def _run(self, name: str, device: Device, row: Command,
             data: bool | None) -> tuple[bool, str]:
        what = row.words(data)
        if isinstance(row.policy, Local):
            # sends nothing on the bus: the transmit gate has nothing to guard (commands.py)
            ok, message = getattr(device, row.build)(*row.args)
            return bool(ok), message
        if not self.gate.enabled:
            return False, f'{name}: {self.gate.refusal(what)}'
        method = getattr(device, row.build)  # at each call: a device may change it
        args = row.args if data is None else (*row.args, data)
        policy = row.policy
        if isinstance(policy, Frames):
            gap = float(getattr(device, 'CONFIG_FRAME_GAP', 0.0)) if policy.paced else 0.0
            return self.frames(name, what, partial(method, *args), gap, policy)
        if isinstance(policy, Exchange):
            ok, message = method(Port(self, name, what), *args)
            return bool(ok), message
        assert isinstance(policy, Carried), policy  # the three policies of commands.py
        return self._carried(name, method(*args))

    # --- Frames ---------------------------------------------------------------------------
    def frames(self, name: str, what: str, build: Callable[[], Frame | Iterable[Frame]],
               gap: float = 0.0, policy: Frames = Frames()) -> tuple[bool, str]:
        """Build a call's frames, wait for the bus once, send them in one batch; answer."""
        try:
            # Validation happens here, before anything is sent; a device builds a write from
            # one configuration object, so a parameter set meanwhile cannot mix two sets.
            built = build()
        except (RefusedCommand, EncodeRangeError) as exc:  # anything else is a bug
            return False, f'{name}: cannot {what}: {exc}; nothing was sent'
        frames = [built] if isinstance(built, Frame) else list(built)
        # A bus still opening (or reconnecting) is waited for once, before the first frame
        # and outside the batch, so calls wait side by side, not one after the other.
        ok, message = self.wait_for_bus(name)
        if not ok:
            return False, f'{name}: cannot {what}: {message}; nothing was sent'
        sent: list[str] = []
        with self.gate.batch():  # the pause after each frame too: nothing else lands there
            for k, frame in enumerate(frames):
                ok, message = self.gate.transmit(frame, wait=False)
                if not ok:
                    done = ', '.join(sent) if sent else 'nothing'
                    left = ', '.join(f'ID {f.arbitration_id}' for f in frames[k:])
                    after = f'. {policy.partial}' if sent and policy.partial else ''
                    return False, (f'{name}: {what} failed at {frame_text(frame)}: '
                                   f'{message}; sent before it: {done}; not sent: {left}'
                                   f'{after}')
                sent.append(frame_text(frame))
                if gap:
                    self._sleep(gap)  # after each frame, as the device's own tool paces it
        apart = f' ({gap * 1000:g} ms apart)' if gap and policy.say_gap else ''
        return True, f'{name}: {what}: sent ' + ', '.join(sent) + apart

    def wait_for_bus(self, name: str, limit: float | None = None) -> tuple[bool, str]:
        """Wait for a (re)opening bus for a call of ``name``: (connected, why not)."""
        ok, message = self.gate.wait_for_bus(limit)
        if ok:
            self._bus_ready(name)
        return ok, message

    # --- Carried ----------------------------------------------------------------------------
    def _carried(self, name: str, carry: Carry) -> tuple[bool, str]:
        """Wait for the bus within the command's timeout, then have the heartbeat carry it."""
        started = time.monotonic()  # the total bound, waiting for the bus included
        ok, message = self.wait_for_bus(name, limit=carry.timeout)
        if not ok:
            return False, f'{name}: {carry.name} not sent: {message}'
        result = carry.carrier.command(carry.command, carry.timeout, started)
        return result.success, f'{name}: {result.message}'

    # --- Exchange ---------------------------------------------------------------------------
    def set_config(self, name: str, values: Mapping[str, Any]) -> tuple[bool, str]:
        """Set instance ``name``'s parameters {key: value}, all or none."""
        return self._set_config(name, values)


class Port:
    """The ``CallPort`` of one call (devices/ports.py): what an ``Exchange`` device uses."""

    def __init__(self, pipeline: Pipeline, name: str, what: str) -> None:
        """Serve one call of instance ``name`` that does ``what``."""
        self._pipeline = pipeline
        self._name = name
        self._what = what

    def __call__(self, frame: Frame, /) -> tuple[bool, str]:
        """Send one frame of the call: the gate, the bus wait, the command log line."""
        return self._pipeline.gate.transmit(frame)

    def send_frames(self, build: Callable[[], Iterable[Frame]]) -> tuple[bool, str]:
        """Build and send frames as a ``Frames`` row does (the call's words)."""
        return self._pipeline.frames(self._name, self._what, build)

    def set_config(self, values: Mapping[str, Any]) -> tuple[bool, str]:
        """Set the instance's parameters {key: value}, all or none."""
        return self._pipeline.set_config(self._name, values)
