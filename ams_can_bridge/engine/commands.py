# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The command side without ROS: a bridge's command rows, the one pipeline, the armed senders.

``Commands`` holds every (instance, row) of a bridge, runs each call through ``Pipeline``
and arms the devices' periodic senders while the gate is enabled and the bus connected.
``Pipeline.call`` never raises: it answers (success, message), is the only place that
refuses while commands are disabled, and a refused call sends nothing. A call's walk, the
policies and the cancelling of calls in flight: doc/architecture.md, "Commands".
"""
from __future__ import annotations

import threading
import time
import traceback
from functools import partial
from typing import Any, Callable, Iterable, Mapping, Protocol

from ams_can_bridge.devices.base import Device
from ams_can_bridge.devices.commands import Carried, Carry, Command, Exchange, Frames, Local
from ams_can_bridge.devices.ports import Armed
from ams_can_bridge.engine.gate import CommandGate, PendingStart
from ams_can_bridge.errors import EncodeRangeError, RefusedCommand
from ams_can_bridge.protocols.common import Frame

SetConfig = Callable[[str, Mapping[str, Any]], tuple[bool, str]]  # (instance, {key: value})


class Call:
    """One call in flight: its name and, once a transition ended it, why."""

    def __init__(self, source: str) -> None:
        """Begin the call ``source`` ('<instance>/<service>')."""
        self.source = source
        self.cancelled = ''  # 'deactivate', ...: set once, by cancel_calls


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
    """Refuse, build, wait, send, answer: every command of every device (doc/architecture.md)."""

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
        self._flight = threading.Condition()  # the calls in flight
        self._calls: set[Call] = set()

    def call(self, name: str, device: Device, row: Command, data: bool | None = None,
             source: str | None = None) -> tuple[bool, str]:
        """Run one call of ``row`` on instance ``name``: (success, answer); never raises."""
        source = source or f'{name}/{row.service}'
        call = Call(source)
        with self._flight:
            self._calls.add(call)
        try:
            with self.gate.calling(source):
                ok, message = self._run(name, device, row, data, call)
        except Exception as exc:  # a bug, not a refusal: say so, keep the traceback
            self._log.error(f'{source}: internal error:\n' + traceback.format_exc())
            ok, message = False, (f'{source}: internal error: {type(exc).__name__}: {exc}; '
                                  'see the log')
        finally:
            with self._flight:
                self._calls.discard(call)
                self._flight.notify_all()
        if call.cancelled and not ok:
            message = f'cancelled by {call.cancelled}: {message}'
        answer = f'{source}: answered success={ok}: {message}'
        if ok:
            self._log.info(answer)
        else:
            self._log.warning(answer)
        return ok, message

    # --- the calls in flight (lifecycle transitions) -------------------------------------
    def in_flight(self) -> int:
        """Return how many calls run now."""
        with self._flight:
            return len(self._calls)

    def cancel_calls(self, why: str) -> int:
        """End every call in flight (answered 'cancelled by <why>'); return how many."""
        with self._flight:
            for call in self._calls:
                call.cancelled = call.cancelled or why
            count = len(self._calls)
        self.gate.end_waits()  # a call waiting for the bus returns now
        return count

    def wait_calls(self, timeout: float) -> bool:
        """Wait up to timeout s until no call is in flight; True when none is."""
        deadline = time.monotonic() + timeout
        with self._flight:
            return self._flight.wait_for(lambda: not self._calls,
                                         max(0.0, deadline - time.monotonic()))

    def _run(self, name: str, device: Device, row: Command,
             data: bool | None, call: Call) -> tuple[bool, str]:
        what = row.words(data)
        if isinstance(row.policy, Local):
            # sends nothing on the bus: the gate has nothing to guard (devices/commands.py)
            ok, message = getattr(device, row.build)(*row.args)
            return bool(ok), message
        if not self.gate.enabled:
            return False, f'{name}: {self.gate.refusal(what)}'
        method = getattr(device, row.build)  # at each call: a device may change it
        args = row.args if data is None else (*row.args, data)
        policy = row.policy
        if isinstance(policy, Frames):
            gap = float(getattr(device, 'CONFIG_FRAME_GAP', 0.0)) if policy.paced else 0.0
            return self.frames(name, what, partial(method, *args), gap, policy, call=call)
        if isinstance(policy, Exchange):
            port = Port(self, name, what, call)
            if policy.bus_first:  # before the method takes its own lock (devices/commands.py)
                ok, message = self.wait_for_bus(name)
                if not ok:
                    return False, f'{name}: cannot {what}: {message}; nothing was sent'
                port.waited = True
            ok, message = method(port, *args)
            return bool(ok), message
        assert isinstance(policy, Carried), policy  # the other policies of devices/commands.py
        return self._carried(name, method(*args))

    # --- Frames ---------------------------------------------------------------------------
    def frames(self, name: str, what: str, build: Callable[[], Frame | Iterable[Frame]],
               gap: float = 0.0, policy: Frames = Frames(), *, wait: bool = True,
               call: Call | None = None) -> tuple[bool, str]:
        """
        Build a call's frames, wait for the bus once, send them in one batch; answer.

        ``wait=False``: the call has waited for the bus already (a bus lost since fails it).
        """
        try:
            # Validation happens here, before anything is sent; a device builds a write from
            # one configuration object, so a parameter set meanwhile cannot mix two sets.
            built = build()
        except (RefusedCommand, EncodeRangeError) as exc:  # anything else is a bug
            return False, f'{name}: cannot {what}: {exc}; nothing was sent'
        frames = [built] if isinstance(built, Frame) else list(built)
        # A bus still opening (or reconnecting) is waited for once, before the first frame
        # and outside the batch, so calls wait side by side, not one after the other.
        ok, message = self.wait_for_bus(name) if wait else (True, '')
        if not ok:
            return False, f'{name}: cannot {what}: {message}; nothing was sent'
        sent: list[str] = []
        with self.gate.batch():  # the pause after each frame too: nothing else lands there
            for k, frame in enumerate(frames):
                if call is not None and call.cancelled:
                    ok, message = False, f'cancelled by {call.cancelled}'
                else:
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

    def __init__(self, pipeline: Pipeline, name: str, what: str,
                 call: Call | None = None) -> None:
        """Serve one call of instance ``name`` that does ``what``."""
        self._pipeline = pipeline
        self._name = name
        self._what = what
        self._call = call
        self.waited = False  # the pipeline waited for the bus: the frames never wait

    def __call__(self, frame: Frame, /) -> tuple[bool, str]:
        """Send one frame of the call: the gate, the bus wait, the command log line."""
        call = self._call
        if call is not None and call.cancelled:
            return False, f'cancelled by {call.cancelled}; not sent'
        return self._pipeline.gate.transmit(frame, wait=not self.waited)

    def cancelled(self) -> str:
        """Return why a transition ended the call ('' while it runs): its waits end."""
        return self._call.cancelled if self._call is not None else ''

    def send_frames(self, build: Callable[[], Iterable[Frame]]) -> tuple[bool, str]:
        """Build and send frames as a ``Frames`` row does (the call's words)."""
        return self._pipeline.frames(self._name, self._what, build, wait=not self.waited,
                                     call=self._call)

    def set_config(self, values: Mapping[str, Any]) -> tuple[bool, str]:
        """Set the instance's parameters {key: value}, all or none."""
        return self._pipeline.set_config(self._name, values)


START_CHECK_POLL = 0.05  # s between looks for "heard and commands enabled"


class StartCheck:
    """One device's start command: run once when the device is heard while commands are on."""

    def __init__(self, commands: Commands, name: str, row: Command) -> None:
        """Start the thread that waits for the device (it never sends while disabled)."""
        self._commands = commands
        self.name = name
        self.row = row
        self.outcome: tuple[bool, str] | None = None  # (success, answer), once it ran
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f'{name}-check', daemon=True)
        self._thread.start()

    def _run(self) -> None:
        device = self._commands.devices[self.name]
        gate = self._commands.gate
        while not self._stop.wait(START_CHECK_POLL):
            if device.heard() and gate.enabled:
                break
        else:
            return
        self.outcome = self._commands.pipeline.call(
            self.name, device, self.row, source=f'{self.name}/check_config_at_start')

    def stop(self) -> None:
        """End the wait (a check under way finishes first, bounded)."""
        self._stop.set()
        self._thread.join(2.0)


class Commands:
    """Every command row of a bridge through one pipeline; senders armed with the gate."""

    def __init__(self, gate: CommandGate, devices: Mapping[str, Device], log: Log, *,
                 set_config: SetConfig = no_config) -> None:
        """Make each device's senders (armed at once if the gate is), start the checks."""
        self.gate = gate
        self.devices = dict(devices)
        self._log = log
        self.pipeline = Pipeline(gate, log, set_config=set_config, bus_ready=self.fire)
        self.senders: dict[str, list[Armed]] = {}
        for name, device in self.devices.items():
            senders = device.attach_senders(gate.send_periodic, log)
            if senders:
                self.senders[name] = senders
        self._pending: dict[str, PendingStart] = {}
        self._rows = {(name, row.service): row for name, device in self.devices.items()
                      for row in device.COMMANDS}
        gate.add_listener(self.on_commands_enabled)
        if gate.enabled:  # commands_enabled at launch: the bus is not even open yet
            self.on_commands_enabled(True)
        self.start_checks: dict[str, StartCheck] = {}
        for name, device in self.devices.items():
            service = device.start_command()
            if service is not None:
                self.start_checks[name] = StartCheck(self, name, self.row(name, service))

    # --- the rows -------------------------------------------------------------------------
    def rows(self) -> list[tuple[str, Command]]:
        """Return every (instance, row) of the bridge, in device and row order."""
        return [(name, row) for (name, _), row in self._rows.items()]

    def row(self, name: str, service: str) -> Command:
        """Return the row of ``<name>/<service>`` (KeyError: no such command)."""
        return self._rows[(name, service)]

    def call(self, name: str, service: str, data: bool | None = None) -> tuple[bool, str]:
        """Call ``<name>/<service>`` (``data``: a SetBool's request): (success, answer)."""
        return self.pipeline.call(name, self.devices[name], self.row(name, service), data)

    # --- the senders follow the gate ---------------------------------------------------------
    def on_commands_enabled(self, enabled: bool) -> None:
        """Arm every device's senders once the bus is connected; disarm them at once."""
        if not enabled:
            self._disarm(shutdown=False)
            return
        for name, senders in self.senders.items():
            pending = self.gate.start_when_connected(partial(_arm, senders))
            self._pending[name] = pending
            starting = [sender.label for sender in senders if sender.starts_on_arm()]
            if not pending.done and starting:
                verb = 'starts' if len(starting) == 1 else 'start'
                self._log.info(f'{name}: {" and ".join(starting)} {verb} when the CAN bus is '
                               'connected')

    def fire(self, name: str) -> None:
        """Arm the senders of ``name`` now if they wait: a call of it found the bus connected."""
        pending = self._pending.get(name)
        if pending is not None:
            pending.fire()

    def _disarm(self, shutdown: bool) -> None:
        for name, senders in self.senders.items():
            pending = self._pending.pop(name, None)
            if pending is not None:
                pending.cancel()  # after this returns it never starts them
            for sender in senders:
                sender.on_disarm(shutdown)

    def close(self) -> None:
        """Stop every sender and start check; the bridge is shutting down."""
        self.gate.remove_listener(self.on_commands_enabled)
        for check in self.start_checks.values():
            check.stop()
        self._disarm(shutdown=True)


def _arm(senders: list[Armed]) -> None:
    for sender in senders:
        sender.on_arm()
