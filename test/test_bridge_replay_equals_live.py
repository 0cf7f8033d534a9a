# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Replay equals live: a recorded bus played back into a fresh bridge publishes the same data.

Live: the simulators run on a virtual bus, a bridge records it (can.record, candump .log).
Replay: fresh bridges play the recording (can.interface replay) in real time and as fast as
possible, from the .log and from a .blf copy. Reference: the real device classes fed the
recorded frames one by one, without ROS (the state after every frame, in order).

What must hold for every device, live and replayed alike, at any replay rate: the
published BatteryStates are exactly the reference's, one per primary frame, in order, value
for value (NaN where unknown). The bridge snapshots the device state at each primary frame,
so neither a later frame nor a fast replay can change or merge what a message carries.
"""
import os
import time

import can
import pytest

from ams_can_bridge.ros.demo_rig import build_simulators, device_parameters
from ams_can_bridge.ros.demo_rig import DEVICES
from ams_can_bridge.sim.recording import write_log
from ams_can_bridge.sim.runner import SimRunner
from command_rig import battery_topics, Rig
from helpers import device_reference, same, values_of

RECORD_S = 3.0
BANKS = 2
QOS_DEPTH = 10000


def bridge_params(**bus) -> dict:
    values = {'devices': list(DEVICES), **device_parameters(BANKS)}
    values.update({f'can.{key}': value for key, value in bus.items()})
    return values


def start(rig_factory, **bus) -> Rig:
    """Start a bridge on this bus recording every BatteryState of each device."""
    return rig_factory(bridge_params(**bus), topics=battery_topics(DEVICES), depth=QOS_DEPTH,
                       wait_connected=bus.get('interface', 'virtual') == 'virtual')


def published(rig: Rig) -> dict[str, list]:
    """Return the values of each device's present messages (not the 1 Hz stale heartbeat)."""
    return {name: [values_of(m) for m in rig.messages(f'{name}/battery_state') if m.present]
            for name in DEVICES}


def count(rig: Rig) -> int:
    return sum(rig.present_count(f'{name}/battery_state') for name in DEVICES)


def wait_settled(rig: Rig, quiet: float = 0.6, timeout: float = 20.0) -> None:
    """Wait until no new message came for ``quiet`` seconds."""
    deadline = time.monotonic() + timeout
    last, since = count(rig), time.monotonic()
    while time.monotonic() - since < quiet:
        assert time.monotonic() < deadline, 'the bridge kept publishing'
        time.sleep(0.05)
        now = count(rig)
        if now != last:
            last, since = now, time.monotonic()


def reference(path: str) -> dict[str, list]:
    """Feed the log to the real device classes: the values after each primary frame."""
    states = device_reference(path, DEVICES, device_parameters(BANKS))
    return {name: [values for _stamp, values in seq] for name, seq in states.items()}


def check_equal(label: str, published: dict[str, list], states: dict[str, list]) -> None:
    """Assert each device published exactly the reference sequence."""
    for name in DEVICES:
        got, want = published[name], states[name]
        first_diff = next((k for k, (a, b) in enumerate(zip(got, want)) if not same(a, b)),
                          None)
        assert len(got) == len(want) and first_diff is None, (
            f'{label}: {name} published {len(got)} messages for {len(want)} primary frames; '
            f'first difference at message {first_diff}: '
            f'{got[first_diff] if first_diff is not None else None} != '
            f'{want[first_diff] if first_diff is not None else None}')


@pytest.mark.slow
def test_replay_publishes_what_live_published(rig_factory, tmp_path):
    live_log = str(tmp_path / 'live.log')
    live = start(rig_factory, record=live_log)  # waits for the live bus
    sim_bus = can.Bus(interface='virtual', channel=live.channel)
    runner = SimRunner(sim_bus, list(build_simulators(BANKS, DEVICES).values()))
    try:
        runner.start()
        time.sleep(RECORD_S)  # the length of the recording, not a timing assertion
        runner.stop()
        wait_settled(live)
    finally:
        runner.stop()
        live.close()  # closes the recording
        sim_bus.shutdown()
    live_values = published(live)

    states = reference(live_log)
    for name in DEVICES:
        assert len(states[name]) >= 2, f'the recording has {len(states[name])} {name} frames'
    check_equal('live', live_values, states)

    with can.LogReader(live_log) as reader:
        frames = sum(1 for _ in reader)
    blf = str(tmp_path / 'live.blf')
    with can.LogReader(live_log) as reader, can.Logger(blf) as writer:
        for msg in reader:
            writer.on_message_received(msg)

    for path, rate in ((live_log, 1.0), (live_log, 0.0), (blf, 0.0)):
        label = f'replay of {os.path.basename(path)} at rate {rate:g}'
        session = start(rig_factory, interface='replay', channel=path, replay_rate=rate)
        try:
            session.wait(lambda: session.bus_values().get('state') == 'replay finished',
                         RECORD_S / max(rate, 0.1) + 20.0, f'{label} to finish')
            wait_settled(session)
            bus = session.bus_values()
        finally:
            session.close()
        replayed = published(session)
        assert bus['replay'] == 'finished' and bus['frames in'] == str(frames), (label, bus)
        check_equal(label, replayed, states)


@pytest.mark.slow
def test_a_replay_as_fast_as_possible_expires_what_the_log_expires(rig_factory, tmp_path):
    """
    A log with a silent spell, played as fast as possible: the values follow the log's time.

    Every frame of 1.0 .. 2.0 s is cut out, longer than the stale_timeout of every device:
    after it, a value not yet sent again is unknown (NaN) in the log's time, although the
    replay hands the frames on within milliseconds. Timed by the moment of handling, the
    replay published the values from before the spell as fresh.
    """
    full, path = str(tmp_path / 'full.log'), str(tmp_path / 'gap.log')
    write_log(full, list(build_simulators(BANKS, DEVICES).values()), 3.0, start=1_790_000_000.0)
    with can.LogReader(full) as reader, can.Logger(path) as writer:
        for msg in reader:
            if not 1.0 <= msg.timestamp - 1_790_000_000.0 < 2.0:
                writer.on_message_received(msg)
    session = start(rig_factory, interface='replay', channel=path, replay_rate=0.0)
    session.wait(lambda: session.bus_values().get('state') == 'replay finished', 30.0,
                 'the replay to finish')
    wait_settled(session)
    session.close()
    check_equal('replay of a log with a silent spell at rate 0', published(session),
                reference(path))
