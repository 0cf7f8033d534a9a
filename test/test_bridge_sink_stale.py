# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
ros/sink.py: a silent device's messages, kept as bytes and restamped, read as built anew.

The periodic thread publishes every silent device's BatteryState and arrays each second.
They are built once per silent spell and published raw, the BatteryState's header stamp
rewritten in the kept bytes: a subscriber must read exactly what the message objects (the
path the sink takes when the start check fails) give, stamped at each publish, and a new
silent spell after a change (a frame, a parameter) must not repeat the last spell's bytes.
"""
from __future__ import annotations

import pytest
import rclpy
from rclpy.serialization import deserialize_message, serialize_message

from ams_can_bridge import registry
from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.device_set import DeviceSet
from ams_can_bridge.engine.core import Engine
from ams_can_bridge.ros.sink import RosSink
from helpers import Clock, ros_context

pytestmark = pytest.mark.ros

DEVICES = ['ams', 'bms16']  # the AMS has arrays (temperatures), the BMS16 none
PARAMS = {'ams.bank_count': 2, 'bms16.location': 'rear'}
WALL = 1_700_000_000.0


class Tee:
    """The engine's sink: the same calls to every sink given."""

    def __init__(self, *sinks: RosSink) -> None:
        self.sinks = sinks

    def __getattr__(self, what: str):
        return lambda *args: [getattr(sink, what)(*args) for sink in self.sinks]


def recording(sink: RosSink) -> list[tuple[str, str]]:
    """Record (topic, what a subscriber reads, as text) of every publish of a sink."""
    seen: list[tuple[str, str]] = []
    publish = sink.publish

    def record(publisher, msg) -> None:
        kind = publisher.msg_type
        raw = msg if isinstance(msg, bytes) else serialize_message(msg)
        seen.append((publisher.topic_name, repr(deserialize_message(raw, kind))))
        publish(publisher, msg)
    sink.publish = record
    return seen


def test_a_silent_devices_kept_bytes_read_as_its_messages_built_anew_at_each_stamp():
    clock = Clock()
    wall = [WALL]
    with ros_context() as context:
        node = rclpy.create_node('sink_stale_test', context=context)
        try:
            devices = DeviceSet(DEVICES, lambda name, spec: PARAMS.get(name, spec.default),
                                clock=clock)
            arrays = {name: list(d.extra_arrays()) for name, d in devices.devices.items()}
            raw, objects = (RosSink(node, arrays, 'virtual:0', False, alive=lambda: True)
                            for _ in range(2))
            assert raw._raw_telemetry  # the start check passed: the raw path is taken
            objects._raw_telemetry = False  # the path taken when the start check fails
            raw.enabled = objects.enabled = True
            raw_seen, object_seen = recording(raw), recording(objects)
            status = BusStatus(state=BusState.CONNECTED, reason='', frames_in=0,
                               frames_out=0, frames_dropped_tx=0, error_frames=0,
                               reconnects=0, hardware_id='virtual:0')
            engine = Engine(devices, Tee(raw, objects), status_prefix='bridge',
                            interface='virtual', bus_status=lambda: status,
                            now=lambda: wall[0], monotonic=clock)
            sims = [registry.load(registry.SIMULATORS[name])(
                **({'bank_count': 2} if name == 'ams' else {})) for name in DEVICES]
            stamps = []
            t = 0.0
            for spell in range(2):
                for _ in range(40):  # two seconds of frames: every device present
                    for sim in sims:
                        for frame in sim.tick(t):
                            engine.on_frame(frame.arbitration_id, frame.data,
                                            frame.is_extended_id, wall[0])
                    t += 0.05
                    clock.now += 0.05
                    wall[0] += 0.05
                clock.now += 30.0  # silent: every device stale
                if spell == 1:  # a parameter changed while silent: that spell's messages
                    devices.devices['bms16'].configure({'location': 'front'})
                for second in range(3):
                    wall[0] += 1.25
                    engine.publish_stale()
                    stamps.append(wall[0])
            stale = [(topic, text) for topic, text in raw_seen if 'present=False' in text]
        finally:
            node.destroy_node()
    assert raw_seen == object_seen  # every message, present or stale, as the objects read
    # 2 spells x 3 seconds x (2 BatteryStates + the AMS's 2 arrays)
    assert len([1 for topic, _ in raw_seen if topic.endswith('temperatures')]) > 12
    assert len(stale) == 2 * 3 * 2
    for k, stamp in enumerate(stamps):  # each restamped at its own publish
        sec, nanosec = int(stamp), round((stamp - int(stamp)) * 1e9)
        for _, text in stale[2 * k:2 * k + 2]:
            assert f'stamp=builtin_interfaces.msg.Time(sec={sec}, nanosec={nanosec})' in text
    # the first spell's kept bytes were not published again for the second spell
    bms16 = [text for topic, text in stale if topic == '/bms16/battery_state']
    assert ["location='rear'" in text for text in bms16] == [True] * 3 + [False] * 3
    assert all("location='front'" in text for text in bms16[3:])
