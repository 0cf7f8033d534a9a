# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ROS-free model of a bridge under random interleavings (issue 34, the systematic part).

``ModelBridge`` is what the node composes below ``ros/``, driven as the node drives it: the
devices, the gate, the one command pipeline with its periodic senders, the bus (``CanIo``)
and the lifecycle (configure, activate, deactivate, cleanup, shutdown, mirroring
``ros/bridge_node.py``: a transition ends the calls in flight first), on a python-can
virtual channel whose adapter can be unplugged (``PluggableBus``), with simulated AMS,
IVT-S and EVMS3 on the wire that can go silent. Parameter sets go through the node's
ROS-free path (``engine/param_sets.py``: ``set_refusal``, ``apply_set``), so a disarm is
``commands_enabled = false`` exactly as the parameter service applies it.

After every step ``check()`` asserts the invariants (doc/failure_modes.md):

- no frame of the bridge on the wire after a disarm was answered or while inactive (a frame
  already handed to the adapter is on the wire before the answer: the capture's marker,
  sent after the answer, comes after it);
- while armed, active and the bus up, consecutive heartbeats at most one period +
  ``HEARTBEAT_SLACK`` apart, by the times the frames were put on the wire; a gap longer than
  that by no more than the machine kept a separate idle process (``Canary``) waiting at the
  same moment is the machine's, not the bridge's: it is kept in ``ModelBridge.excused``;
- a disarm answered within ``DISARM_BOUND``, whatever is in flight;
- every call answered within its bound (``CALL_BOUND``);
- nothing escapes a thread (the node would exit).

``test/test_engine_interleavings.py`` drives it with hypothesis's ``RuleBasedStateMachine``;
``bench/run.py --only interleavings`` runs it for minutes.
"""
from __future__ import annotations

import collections
import gc
import itertools
import atexit
import os
import subprocess
import sys
import threading
import time
from typing import Any, Callable

import can
from can.interfaces.virtual import VirtualBus
from hypothesis import strategies as st
from hypothesis.stateful import invariant, rule, RuleBasedStateMachine

from ams_can_bridge.can_io import BusConfig, CanIo
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.commands import Commands
from ams_can_bridge.engine.gate import CommandGate
from ams_can_bridge.engine.param_sets import apply_set, set_refusal
from ams_can_bridge.engine.live import settle_heap
from ams_can_bridge.errors import ParamError
from ams_can_bridge.parameters import coerce, ParamSpec
from ams_can_bridge.protocols.ams import DEFAULT_BASE_ID as AMS_BASE
from ams_can_bridge.sim.ams import AmsSimulator
from ams_can_bridge.sim.evms3 import Evms3Simulator
from ams_can_bridge.sim.ivt_s import IvtSSimulator
from ams_can_bridge.sim.runner import SimRunner
from command_bench import Capture
from helpers import gil_like_the_bridge  # noqa: F401 (the machines use it from here)
from shared import collecting_logger

HEARTBEAT = AMS_BASE + 5
HEARTBEAT_SLACK = 0.02  # s beyond one period between heartbeats (the model; live: 0.1)
DISARM_BOUND = 0.1  # s for a disarm's answer
CONNECT_WAIT = 1.0  # s: can.connect_wait of the model
RECONNECT = 0.1  # s: can.reconnect_period of the model
CALL_SLACK = 1.5  # s beyond a call's own bounds (a loaded 2-core machine)
MAX_PENDING = 5  # calls in flight at once (the executor would take 3; the rest queue)
PERIODS = (0.02, 0.05, 0.1)
# Run-time parameters and the values the rules set (the current value among them).
VALUES: dict[str, tuple[Any, ...]] = {
    'ams.heartbeat_period': PERIODS,
    'ams.command_timeout': (0.5, 1.0),
    'ams.charge_current_a': (0.0, 10.0, 12.5),
    'ams.bank_count': (1, 3, 5),
    'ivt_s.command_timeout': (0.3, 0.6),
    'evms3.read_timeout': (0.3, 0.6),
    'evms3.stale_timeout': (1.0, 2.0),
}
SCALAR = ParamSpec('command_timeout', float, 1.0, 'a scalar', 0.1, 60.0)
# Made once: building a 3,000,000-element list holds the GIL for ~20 ms in the test's own
# thread, a stall that is not the bridge's (rclpy hands the node a value already built).
HUGE = {size: [0.5] * size for size in (1_000, 3_000_000)}
# Collections of the last minutes as (wall start, seconds, generation): a heartbeat gap names
# the ones it overlaps, so a broken bound says whether the collector stopped every thread.
GC_PAUSES: collections.deque[tuple[float, float, int]] = collections.deque(maxlen=512)
_gc_started = [0.0]


def _time_collections(phase: str, info: dict[str, int]) -> None:
    if phase == 'start':
        _gc_started[0] = time.time()
    else:
        GC_PAUSES.append((_gc_started[0], time.time() - _gc_started[0], info['generation']))


gc.callbacks.append(_time_collections)


# A process of its own that sleeps 5 ms at a time and reports each wake-up late by 5 ms or
# more: how long the machine kept an idle program waiting. It shares no interpreter with the
# bridge, so a stall of the bridge's own making (the GIL held, a lock) never shows in it.
_CANARY = (
    'import sys, time\n'
    'due = time.monotonic()\n'
    'while True:\n'
    '    due += 0.005\n'
    '    time.sleep(max(0.0, due - time.monotonic()))\n'
    '    late = time.monotonic() - due\n'
    '    if late >= 0.005:\n'
    '        print(f"{time.time():.6f} {late:.6f}", flush=True)\n'
    '        due = time.monotonic()\n'
)


class Canary:
    """The machine's own delays, from ``_CANARY``: (wall time of the wake-up, s late)."""

    _started: 'Canary | None' = None

    def __init__(self) -> None:
        self.delays: collections.deque[tuple[float, float]] = collections.deque(maxlen=4096)
        self.process = subprocess.Popen([sys.executable, '-c', _CANARY],
                                        stdout=subprocess.PIPE, text=True)
        atexit.register(self.process.kill)
        threading.Thread(target=self._read, name='canary-reader', daemon=True).start()

    @classmethod
    def started(cls) -> 'Canary':
        """Return the one canary of this test process (started at the first call)."""
        if cls._started is None:
            cls._started = cls()
        return cls._started

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            woke, late = line.split()
            self.delays.append((float(woke), float(late)))

    def delay(self, a: float, b: float) -> float:
        """Return the longest the machine kept the canary waiting from a to just after b."""
        return max((late for woke, late in list(self.delays) if a < woke <= b + 0.05),
                   default=0.0)


TRANSITIONS = {
    'unconfigured': ('configure', 'shutdown'),
    'inactive': ('activate', 'cleanup', 'shutdown'),
    'active': ('deactivate', 'shutdown'),
    'finalized': (),
}
_channels = itertools.count()


class InvariantBroken(AssertionError):
    """An invariant of doc/failure_modes.md did not hold."""


# --- an adapter that can be unplugged ---------------------------------------------------------
UNPLUGGED: set[str] = set()  # the channels whose adapter is out


class PluggableBus(can.BusABC):
    """A python-can virtual bus whose adapter can be pulled (``UNPLUGGED``)."""

    def __init__(self, channel: str, **kwargs: Any) -> None:
        if channel in UNPLUGGED:
            raise can.CanInitializationError(f'{channel}: no such adapter (unplugged)')
        self.channel_info = channel
        self._bus = VirtualBus(channel=channel)
        super().__init__(channel=channel)

    def _check(self) -> None:
        if self.channel_info in UNPLUGGED:
            raise can.CanOperationError(f'{self.channel_info}: adapter unplugged')

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._check()
        self._bus.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        self._check()
        return self._bus._recv_internal(min(timeout or 0.05, 0.05))

    def shutdown(self) -> None:
        self._bus.shutdown()
        super().shutdown()


# python-can looks an interface up in BACKENDS and checks it against can.util's copy of
# VALID_INTERFACES (a frozenset): both learn the test's own interface
can.interfaces.BACKENDS['pluggable'] = (__name__, 'PluggableBus')
can.util.VALID_INTERFACES = can.interfaces.VALID_INTERFACES | {'pluggable'}  # type: ignore
# ... and the bridge's own check of can.interface (can_io/config.py), for the live run
can.interfaces.VALID_INTERFACES = can.util.VALID_INTERFACES  # type: ignore


class Pending:
    """One call in flight in a thread of its own: its answer and when it came."""

    def __init__(self, name: str, run: Callable[[], tuple[bool, str]], bound: float) -> None:
        self.name = name
        self.bound = bound
        self.started = time.monotonic()
        self.answer: tuple[bool, str] | None = None
        self.took = 0.0
        self.thread = threading.Thread(target=self._run, args=(run,), daemon=True,
                                       name=f'model-call {name}')
        self.thread.start()

    def _run(self, run: Callable[[], tuple[bool, str]]) -> None:
        self.answer = run()
        self.took = time.monotonic() - self.started


class ModelBridge:
    """The bridge below ROS under one random sequence (module docstring)."""

    heartbeat_slack = HEARTBEAT_SLACK
    disarm_bound = DISARM_BOUND
    # Gaps beyond the bound by no more than the machine delayed the canary then:
    # (start, gap, the canary's delay), s; the bench reports them.
    excused: set[tuple[float, float, float]] = set()

    def __init__(self, label: str = 'model') -> None:
        """Make the wire and the simulators; the bridge starts unconfigured."""
        self.channel = f'interleave-{label}-{os.getpid()}-{next(_channels)}'
        self.capture = Capture(self.channel)
        self.canary = Canary.started()
        self.log, self.lines = collecting_logger(self.channel)
        self.failures: list[str] = []
        self._old_hook = threading.excepthook
        threading.excepthook = self._thread_failed
        self.sims = [AmsSimulator(bank_count=3, precharge_time=0.2), IvtSSimulator(),
                     Evms3Simulator()]
        self.runner: SimRunner | None = None
        self.devices_talk(True)
        self.values = {name: values[0] for name, values in VALUES.items()}
        self.values['ams.heartbeat_period'] = 0.05
        self.state = 'unconfigured'
        self.enabled = False
        self.plugged = True
        self.gate: CommandGate | None = None
        self.commands: Commands | None = None
        self.io: CanIo | None = None
        self.device_set: DeviceSet | None = None
        self.pending: list[Pending] = []
        self.steps: list[str] = []
        self.silent_mark: int | None = 0  # capture mark after which the bridge is quiet
        self.window: float | None = None  # armed, active, bus up since (monotonic)
        self.window_periods: set[float] = set()
        self.disarms: list[float] = []
        self.sent_ids: set[tuple[int, bool]] = set()

    def _thread_failed(self, args: Any) -> None:
        self.failures.append(f'thread {args.thread.name}: {args.exc_type.__name__}: '
                             f'{args.exc_value}')
        self._old_hook(args)

    # --- the world around the bridge -------------------------------------------------------
    def devices_talk(self, talk: bool) -> None:
        """Start or stop the simulated devices (a silent AMS, IVT-S and EVMS3)."""
        if talk and self.runner is None:
            self.runner = SimRunner(can.Bus(interface='virtual', channel=self.channel),
                                    self.sims, tick_period=0.005)
            self.runner.start()
        elif not talk and self.runner is not None:
            self.runner.stop()
            self.runner.bus.shutdown()
            self.runner = None

    def plug(self, plugged: bool) -> None:
        """Pull the bridge's adapter out, or put it back."""
        self.plugged = plugged
        if plugged:
            UNPLUGGED.discard(self.channel)
        else:
            UNPLUGGED.add(self.channel)
            self._window(False)

    # --- the lifecycle, as ros/bridge_node.py drives it --------------------------------------
    def transition(self, name: str) -> None:
        """Run one valid transition of the current state."""
        assert name in TRANSITIONS[self.state], (self.state, name)
        getattr(self, f'_{name}')()

    def _configure(self) -> None:
        self.gate = CommandGate(f'pluggable:{self.channel}', allowed=True,
                                connect_wait=CONNECT_WAIT, logger=self.log)
        self.device_set = DeviceSet(['ams', 'ivt_s', 'evms3'], self._value)
        devices = self.device_set.devices
        self.sent_ids = {key for device in devices.values() for key in device.sent_ids()}
        self.commands = Commands(self.gate, devices, self.log, set_config=self._set_config)
        self.io = CanIo(BusConfig(interface='pluggable', channel=self.channel,
                                  reconnect_period=RECONNECT),
                        self._on_frame, self.device_set.filters, self.log)
        self.gate.attach_bus(self.io)
        self.io.start()
        settle_heap()  # as the node's configure does
        self.state = 'inactive'

    def _value(self, name: str, spec: ParamSpec) -> Any:
        fixed = {'evms3.config_request': True, 'ams.bank_count': 3}
        return self.values.get(name, fixed.get(name, spec.default))

    def _on_frame(self, arbitration_id: int, data: bytes, extended: bool, stamp: float) -> None:
        assert self.device_set is not None
        self.device_set.handle_frame(arbitration_id, data, extended, stamp)

    def _activate(self) -> None:
        self.state = 'active'

    def _deactivate(self) -> None:
        assert self.commands is not None and self.gate is not None
        self.state = 'inactive'
        self.commands.pipeline.cancel_calls('deactivate')
        self.disarm(how='the bridge was deactivated')
        self.commands.pipeline.wait_calls(5.0)
        self._quiet()

    def _cleanup(self) -> None:
        self._release('cleanup')
        self.state = 'unconfigured'

    def _shutdown(self) -> None:
        self._release('shutdown')
        self.state = 'finalized'

    def _release(self, why: str) -> None:
        if self.commands is not None and self.gate is not None and self.io is not None:
            self.commands.pipeline.cancel_calls(why)
            self.gate.attach_bus(None)
            self.commands.close()
            self.commands.pipeline.wait_calls(5.0)
            self.io.stop()
        self.commands = self.gate = self.io = None
        self.device_set = None
        self.enabled = False
        self._window(False)
        self._quiet()

    # --- parameter sets, through engine/param_sets.py ----------------------------------------
    def set_param(self, name: str, value: Any, copies: int = 1) -> str | None:
        """Set ``name = value`` ``copies`` times in one go; the refusal or None."""
        devices = self.device_set.devices if self.device_set is not None else {}
        for _ in range(copies):
            refused = set_refusal(name, value, gate=self.gate, devices=devices,
                                  active=self.state == 'active', log=self.log,
                                  configured=self.gate is not None)
            if refused:
                return refused
            self.values[name] = value
            if self.gate is not None:
                apply_set({name: value}, gate=self.gate, devices=devices, log=self.log)
        if name == 'ams.heartbeat_period':
            self.window_periods.add(float(value))
        return None

    def huge_set(self, name: str, size: int) -> str:
        """Set a list of ``size`` values on a scalar: refused on its type, return why."""
        try:
            coerce(name, SCALAR, HUGE[size])
        except ParamError as exc:
            return str(exc)
        raise InvariantBroken(f'{name}: a list of {size} values was accepted on a scalar')

    def _set_config(self, name: str, values: dict[str, Any]) -> tuple[bool, str]:
        for key, value in values.items():
            refused = self.set_param(f'{name}.{key}', value)
            if refused:
                return False, refused
        return True, ''

    def arm(self) -> None:
        """Set commands_enabled true (refused unless active)."""
        if self.set_param('commands_enabled', True) is None:
            self.enabled = True
            self.silent_mark = None  # armed: the bridge may send
            self._window(self.plugged)

    def disarm(self, how: str = '') -> None:
        """Set commands_enabled false; it must be answered within DISARM_BOUND."""
        started = time.monotonic()
        if self.gate is not None:
            self.gate.set_enabled(False, how=how)
        took = time.monotonic() - started
        self.disarms.append(took)
        self.enabled = False
        self._window(False)
        self._quiet()
        if took > self.disarm_bound:
            raise InvariantBroken(f'the disarm was answered after {took * 1000:.0f} ms '
                                  f'with {len(self.live_calls())} call(s) in flight')

    # --- calls -------------------------------------------------------------------------------
    def rows(self) -> list[tuple[str, str, bool]]:
        """Return every command of the bridge as (instance, service, takes data)."""
        if self.commands is None:
            return []
        return [(name, row.service, row.request.name == 'SET_BOOL')
                for name, row in self.commands.rows()]

    def call(self, name: str, service: str, data: bool | None) -> None:
        """Start one call in a thread of its own (as the executor would)."""
        commands = self.commands
        assert commands is not None
        bound = CONNECT_WAIT + 10 * max(self.values['ivt_s.command_timeout'],
                                        self.values['evms3.read_timeout']) \
            + self.values['ams.command_timeout'] + CALL_SLACK
        self.pending.append(Pending(f'{name}/{service}',
                                    lambda: commands.call(name, service, data), bound))

    def live_calls(self) -> list[Pending]:
        """Return the calls not answered yet."""
        return [p for p in self.pending if p.answer is None]

    # --- the invariants ----------------------------------------------------------------------
    def _quiet(self) -> None:
        """From now on the bridge must send nothing (until armed again)."""
        self.capture.sync()
        self.silent_mark = self.capture.mark()

    def _window(self, open_: bool) -> None:
        if open_ and self.window is None and self.enabled and self.state == 'active':
            self.window = time.time()  # the wire's clock (Capture.wire_times)
            self.window_periods = {float(self.values['ams.heartbeat_period'])}
        elif not open_:
            self.window = None

    def bridge_frames(self, mark: int) -> list[tuple[float, Any]]:
        """Return the bridge's own frames captured since mark (not the simulators')."""
        return [(t, f) for t, f in self.capture.since(mark)
                if (f.arbitration_id, f.is_extended_id) in self.sent_ids]

    def check(self) -> None:
        """Assert every invariant now (module docstring); InvariantBroken says which."""
        if self.failures:
            raise InvariantBroken(f'a thread failed: {self.failures}')
        if self.silent_mark is not None:
            self.capture.sync()
            sent = self.bridge_frames(self.silent_mark)
            if sent:
                raise InvariantBroken(f'{len(sent)} frame(s) after a disarm or while '
                                      f'inactive, first {sent[0][1]}')
        now = time.monotonic()
        for pending in self.pending:
            took = pending.took if pending.answer is not None else now - pending.started
            if took > pending.bound:
                raise InvariantBroken(f'{pending.name} answered after {took:.2f} s (bound '
                                      f'{pending.bound:.2f} s)' if pending.answer else
                                      f'{pending.name} not answered after {took:.2f} s')
        self.pending = [p for p in self.pending if p.answer is None]
        if self.window is not None and self.bus_connected():
            self._check_heartbeat()

    def _check_heartbeat(self) -> None:
        assert self.window is not None
        start = self.window + max(self.window_periods) + 0.2  # the heartbeat has started
        times = [t for t in self.capture.wire_times_of(HEARTBEAT) if t >= start]
        bound = max(self.window_periods) + self.heartbeat_slack
        for a, b in zip(times, times[1:]):
            if b - a <= bound:
                continue
            machine = self.canary.delay(a, b)
            if b - a <= bound + machine:  # the machine held every program back as long
                self.excused.add((round(a, 6), round(b - a, 4), round(machine, 4)))
                continue
            raise InvariantBroken(f'a {(b - a) * 1000:.0f} ms heartbeat gap (bound '
                                  f'{bound * 1000:.0f} ms, the machine delayed a separate '
                                  f'process by {machine * 1000:.0f} ms then); '
                                  f'{self._why_late(a, b)}')

    def _why_late(self, a: float, b: float) -> str:
        """Say what else happened in a gap: collections, the sender's count, the load."""
        pauses = [f'{seconds * 1000:.0f} ms (generation {generation})'
                  for start, seconds, generation in list(GC_PAUSES)
                  if start < b and start + seconds > a and seconds >= 0.002]
        master = getattr(self.device_set.devices.get('ams') if self.device_set else None,
                         'master', None)
        missed = master.stats.missed_slots if master is not None else 'n/a'
        load = ', '.join(f'{x:.1f}' for x in os.getloadavg())
        return (f'garbage collections of 2 ms or more in it: {", ".join(pauses) or "none"}; '
                f'slots the '
                f'sender counted as missed since its start: {missed}; load average {load}')

    def bus_connected(self) -> bool:
        """Tell whether the bridge's bus is connected now."""
        return self.io is not None and self.io.status().connected

    def bus_up(self) -> None:
        """Wait until a plugged adapter is connected again, then open the heartbeat window."""
        if self.state != 'unconfigured' and self.state != 'finalized' and self.plugged:
            deadline = time.monotonic() + 5.0
            while not self.bus_connected() and time.monotonic() < deadline:
                time.sleep(0.01)
            self._window(True)

    def close(self) -> None:
        """Shut everything down (the sequence ended); wait for the calls, bounded."""
        if self.state != 'finalized':
            self._release('shutdown')
        for pending in self.pending:
            pending.thread.join(10.0)
        self.devices_talk(False)
        UNPLUGGED.discard(self.channel)
        self.capture.close()
        threading.excepthook = self._old_hook


class Checked(RuleBasedStateMachine):
    """What the model's and the live machine share: the world's rules, the invariants."""

    bridge: ModelBridge

    def step(self, text: str) -> None:
        """Note what a step does: the bench prints the steps of a broken sequence."""
        self.bridge.steps.append(f'{time.monotonic():.3f} {text}')

    @rule(plugged=st.booleans())
    def adapter(self, plugged: bool) -> None:
        self.step('adapter ' + ('plugged in' if plugged else 'unplugged'))
        self.bridge.plug(plugged)
        self.bridge.bus_up()

    @rule(talk=st.booleans())
    def devices(self, talk: bool) -> None:
        self.step('devices ' + ('talk' if talk else 'silent'))
        self.bridge.devices_talk(talk)

    @rule(seconds=st.sampled_from([0.02, 0.1, 0.3]))
    def time_passes(self, seconds: float) -> None:
        self.step(f'{seconds:g} s pass')
        time.sleep(seconds)

    @invariant()
    def invariants_hold(self) -> None:
        self.bridge.check()

    def teardown(self) -> None:
        try:
            self.bridge.check()
        finally:
            self.bridge.close()
