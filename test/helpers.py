# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Helpers shared by the tests: hand-driven clock, polling, ROS context, DBC and codec checks."""
from __future__ import annotations

import contextlib
import itertools
import logging
import math
import os
import signal
import struct
import subprocess
import sys
import threading
import time
from typing import Any, Callable, Iterable, Iterator
import warnings

import canmatrix.formats
import cantools
import rclpy
from rclpy.context import Context

from ams_can_bridge import registry
from ams_can_bridge.can_io.replay import open_log
from ams_can_bridge.devices.base import device_params
from ams_can_bridge.errors import MalformedFrameError

_bridges = itertools.count()


def f32(value: float) -> float:
    """Round as the float32 fields of BatteryState do on the wire."""
    return struct.unpack('<f', struct.pack('<f', value))[0]


def values_of(msg_or_report: Any) -> tuple:
    """Return the published values of a BatteryState or BatteryReport (no stamp)."""
    m = msg_or_report
    return (f32(m.voltage), f32(m.current), f32(m.charge), f32(m.capacity),
            f32(m.design_capacity), f32(m.percentage), f32(m.temperature),
            int(m.power_supply_status), int(m.power_supply_health),
            int(m.power_supply_technology), bool(m.present),
            tuple(f32(v) for v in m.cell_voltage),
            tuple(f32(v) for v in m.cell_temperature))


def same(a: Any, b: Any) -> bool:
    """Compare nested tuples of values, NaN equal to NaN."""
    if isinstance(a, tuple):
        return (isinstance(b, tuple) and len(a) == len(b)
                and all(same(x, y) for x, y in zip(a, b)))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


# Protocol ranges (doc/protocols.md): nothing a frame can carry lies outside these.
INT32_SCALED = 2 ** 31 / 1000  # IVT-S results: int32 mV / mA / mAs
BOUNDS = {
    'voltage': (-INT32_SCALED, INT32_SCALED),  # IVT-S U1 when an AMS uses the shunt
    'current': (-INT32_SCALED, INT32_SCALED),
    'charge': (-INT32_SCALED, INT32_SCALED),
    'capacity': (0.0, 1e6),
    'design_capacity': (0.0, 1e6),
    'percentage': (0.0, 1.0),
    'temperature': (-273.15, 3276.7),  # S16 0.1 degC is the widest temperature encoding
}
CELL_VOLTAGE = (0.0, 65.535)  # uint16 mV is the widest cell encoding
CELL_TEMPERATURE = (-273.15, 3276.7)


def unphysical(msg: Any) -> list[str]:
    """List the fields of msg that are neither NaN nor a value the protocols allow."""
    bad = []

    def check(name: str, value: float, low: float, high: float) -> None:
        if not math.isnan(value) and not (math.isfinite(value) and low <= value <= high):
            bad.append(f'{name}={value!r}')
    for name, (low, high) in BOUNDS.items():
        check(name, getattr(msg, name), low, high)
    for i, value in enumerate(msg.cell_voltage):
        check(f'cell_voltage[{i}]', value, *CELL_VOLTAGE)
    for i, value in enumerate(msg.cell_temperature):
        check(f'cell_temperature[{i}]', value, *CELL_TEMPERATURE)
    if msg.power_supply_status > 4 or msg.power_supply_health > 8 \
            or msg.power_supply_technology > 8:
        bad.append('enum out of range')
    return bad


def device_reference(path: str, names: Iterable[str],
                     parameters: dict[str, Any]) -> dict[str, list[tuple[float, tuple]]]:
    """
    Feed a log to the real device classes, without ROS: (stamp, values) per primary frame.

    Each device gets its type's defaults and the '<name>.<key>' entries of parameters; its
    clock is the log's timestamps, so staleness follows the recording. The independent
    reference of what the bridge, a replay and log2bag must publish.
    """
    now = [0.0]
    devices = {}
    for name in names:
        cls = registry.device_class(name)
        params = {spec.key: spec.default for spec in device_params(cls)}
        params.update({key[len(name) + 1:]: value for key, value in parameters.items()
                       if key.startswith(name + '.')})
        devices[name] = cls(name, params, clock=lambda: now[0])
    if 'ams' in devices and 'ivt_s' in devices:
        devices['ams'].attach_current_sensor(devices['ivt_s'])
    states: dict[str, list] = {name: [] for name in devices}
    reader = open_log(path)
    try:
        for msg in reader:
            now[0] = msg.timestamp
            for name, device in devices.items():
                if ((msg.arbitration_id, msg.is_extended_id) in device.frame_ids
                        and device.handle_frame(msg.arbitration_id, bytes(msg.data), now[0])):
                    states[name].append((msg.timestamp, values_of(device.battery_report())))
    finally:
        reader.stop()
    return states


class Clock:
    """A hand-driven monotonic clock, so staleness is tested without sleeping."""

    def __init__(self, now: float = 100.0) -> None:
        self.now = now

    def __call__(self) -> float:
        return self.now


def wait_for(predicate: Callable[[], Any], timeout: float = 5.0,
             what: str = 'condition', poll: float = 0.005) -> Any:
    """
    Poll predicate until it is true and return its value; fail the test naming what.

    The one wait of the test suite (bounded: a timeout is an AssertionError, never a hang,
    never a silent False). "Nothing was sent" is never shown by sleeping: a frame sent by a
    call is shown absent with a marker frame sent after it (``command_rig.Capture.sync``),
    a periodic sender shown stopped with ``assert_ended`` on its thread.
    """
    deadline = time.monotonic() + timeout
    while True:
        result = predicate()
        if result:
            return result
        if time.monotonic() >= deadline:
            raise AssertionError(f'timed out after {timeout} s waiting for {what}')
        time.sleep(poll)


def interrupt(proc: Any, timeout: float = 20.0) -> str:
    """Stop a child process as Ctrl-C does (killed after timeout); return its output."""
    proc.send_signal(signal.SIGINT)
    try:
        return proc.communicate(timeout=timeout)[0]
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.communicate(timeout=10)[0]


def assert_ended(thread: threading.Thread | None, what: str, timeout: float = 5.0) -> None:
    """
    Assert that a sender's thread has ended (joined, bounded): it can send nothing any more.

    How a test shows a periodic sender stopped without listening for a while: a thread that
    has returned never sends again, however long one waited. ``stop()``-style calls join
    their thread themselves; the join here only bounds the check when one does not.
    """
    assert thread is not None, f'{what}: no thread to check (was it ever started?)'
    thread.join(timeout)
    assert not thread.is_alive(), f'{what}: its thread {thread.name!r} still runs'


@contextlib.contextmanager
def ros_context() -> Iterator[Context]:
    """Yield an initialised rclpy context of its own; shut it down afterwards."""
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)


@contextlib.contextmanager
def every_device_bridge(tag: str) -> Iterator[Any]:
    """
    Yield a bridge node with one instance of every device type on a virtual bus, not spun.

    For tests that read what the node declares (parameters, services), not what it does.
    """
    from rclpy.parameter import Parameter

    from ams_can_bridge.ros.bridge_node import BridgeNode  # the node: only where needed
    from dbc_fixtures import OUR_PARAMS  # a dbc instance needs its files
    with ros_context() as context:
        node = BridgeNode(context=context, parameter_overrides=[
            Parameter('devices', value=list(registry.DEVICE_TYPES)),
            *(Parameter(f'dbc.{key}', value=value) for key, value in OUR_PARAMS.items()),
            Parameter('pack.members', value=['evms3', 'bms16']),
            Parameter('can.interface', value='virtual'),
            Parameter('can.channel', value=f'{tag}-{os.getpid()}-{next(_bridges)}')])
        try:
            yield node
        finally:
            node.destroy_node()


def assert_decodes_or_malformed(codec: object, frame_id: int, data: bytes) -> None:
    """Assert that codec reads the frame, or refuses it with a MalformedFrameError naming it."""
    try:
        reading = codec.decode(frame_id, data)
    except MalformedFrameError as exc:
        assert exc.arbitration_id == frame_id, (exc.arbitration_id, frame_id)
    else:
        assert reading is not None, f'0x{frame_id:X} {data.hex()} decoded to None'


def load_dbc_strictly(path: str, caplog: Any) -> tuple[Any, Any]:
    """
    Load a DBC in cantools (strict) and in canmatrix; fail on any warning of either.

    Return (the cantools database, the canmatrix matrix). caplog is pytest's fixture.
    """
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        db = cantools.database.load_file(path, strict=True)
        with caplog.at_level(logging.WARNING):
            matrix = canmatrix.formats.loadp_flat(path)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    return db, matrix


def run_sim(sim: Any, device: Any, seconds: float, step: float = 0.05,
            start: float = 0.0) -> list:
    """Tick a simulator for ``seconds`` and feed every frame to the device; return the frames."""
    frames = []
    t = start
    while t < start + seconds - 1e-9:
        for frame in sim.tick(t):
            frames.append(frame)
            if device is not None:
                device.handle_frame(frame.arbitration_id, frame.data, t)
        t += step
    return frames


@contextlib.contextmanager
def gil_like_the_bridge() -> Iterator[None]:
    """Hand the GIL over as the bridge's executable does, meanwhile (GIL_SWITCH_INTERVAL)."""
    from ams_can_bridge.ros.bridge_main import GIL_SWITCH_INTERVAL
    old = sys.getswitchinterval()
    sys.setswitchinterval(GIL_SWITCH_INTERVAL)
    try:
        yield
    finally:
        sys.setswitchinterval(old)
