# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What several test files share: fakes that stand in for a bus or a log, and golden data.

Golden frames and configurations are written by hand from the vendors' sources (each file
that defines them says which); test files import them from here, never from one another.
"""
from __future__ import annotations

import functools
import logging
import threading
from pathlib import Path
from typing import Any, Callable

import can
import yaml

from ams_can_bridge.bus_state import BusState, BusStatus
from ams_can_bridge.errors import CanSendError
from ams_can_bridge import registry
from ams_can_bridge.offline.frame_tuples import message_frame
from ams_can_bridge.offline.log_frames import LogFrames
from ams_can_bridge.probe.main import main as probe_main
from ams_can_bridge.probe.recognise import Findings
from ams_can_bridge.probe.traffic import Traffic
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.evms3 import Evms3Settings
from ams_can_bridge.ros.demo_rig import device_parameters, DEVICES
from dbc_fixtures import OUR_PARAMS
from helpers import f32


class FakeBus:
    """A bus whose state the test sets (the gate's ``BusPort``); records every frame sent."""

    def __init__(self, state: BusState = BusState.CONNECTED) -> None:
        self.state = state
        self.reason = ''
        self.sent: list[Frame] = []
        self.fail = ''  # set: every send fails with it (CanSendError)
        self.before_send: Callable[[Frame], None] | None = None  # called before each send
        self.cv = threading.Condition()

    def set_state(self, state: BusState, reason: str = '') -> None:
        with self.cv:
            self.state, self.reason = state, reason
            self.cv.notify_all()

    def status(self) -> BusStatus:
        return BusStatus(self.state, self.reason, 0, len(self.sent), 0, 0, 0, 'fake:0')

    def wait_connected(self, timeout: float) -> BusStatus:
        with self.cv:
            self.cv.wait_for(lambda: self.state == BusState.CONNECTED, timeout)
        return self.status()

    def send(self, frame: Frame) -> None:
        if self.before_send is not None:
            self.before_send(frame)
        if self.fail:
            raise CanSendError(self.fail)
        self.sent.append(frame)


class Lines(logging.Handler):
    """Collect log records as (level, text)."""

    def __init__(self) -> None:
        super().__init__()
        self.lines: list[tuple[int, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append((record.levelno, record.getMessage()))

    def at(self, level: int) -> list[str]:
        """Return the texts logged at ``level``."""
        return [text for lvl, text in self.lines if lvl == level]


def collecting_logger(tag: str) -> tuple[logging.Logger, Lines]:
    """Return a fresh stdlib logger (DEBUG, not propagated) and what it collects."""
    logger = logging.getLogger(f'{tag}.{id(object())}')
    logger.propagate = False
    logger.setLevel(logging.DEBUG)
    lines = Lines()
    logger.addHandler(lines)
    return logger, lines


def sent(bridge: Any, mark: int = 0) -> list[tuple[int, bytes, bool]]:
    """Return (id, data, 29-bit) of every frame a Rig's or Bench's capture saw after mark."""
    return [(f.arbitration_id, f.data, f.is_extended_id)
            for _, f in bridge.capture.since(mark)]


# --- BMS16: golden frames written by hand from doc/protocols.md section 4 ----------------------
BMS16_CONFIG = {
    'cells': 14.0,             # 14 (written as 14.0: YAML spelling must not matter)
    'pack_capacity_ah': 100,   # 10 Ah/bit -> 10
    'soc_warning_pct': 20,     # 20
    'full_voltage_v': 58.0,    # 58
    'warn_current_a': 150,     # 10 A/bit -> 15
    'trip_current_a': 300.0,   # 30
    'temperature_limit_c': 60,  # 60
    'min_cell_v': 2.8,         # 0.05 V/bit -> 56
    'max_cell_v': 3.65,        # 73
    'hysteresis_v': 0.1,       # 2
    'balance_v': 3.5,          # 70
    'shunt_size_a': 200,       # code 2
}
BMS16_504 = bytes([14, 10, 20, 58, 15, 30, 60, 56])
BMS16_505 = bytes([73, 2, 70, 2])


def bms16_params(enabled=True, config=BMS16_CONFIG, skip=()):
    params = {'devices': ['bms16'], 'commands_allowed': True, 'commands_enabled': enabled}
    params.update({f'bms16.config.{k}': v for k, v in config.items() if k not in skip})
    return params


# --- EVMS3: golden frames written by hand from doc/protocols.md section 3 (29-bit IDs) ----------
EVMS3_CONFIG = {
    'pack_capacity_ah': 100, 'soc_warning_pct': 20, 'full_voltage_v': 400.0,
    'warn_current_a': 200, 'trip_current_a': 300, 'temp_warning_c': 60,
    'min_aux_voltage_v': 11, 'min_isolation_pct': 50,
    'tacho_ppr': 2, 'fuel_gauge_full_pct': 90, 'fuel_gauge_empty_pct': 10,
    'temp_gauge_hot_pct': 80, 'temp_gauge_cold_pct': 20, 'bms_min_cell_v': 2.8,
    'bms_max_cell_v': 3.65, 'balance_v': 3.5, 'balance_mode': 'static',
    'bms_hysteresis_v': 0.05, 'bms_min_temp_c': 0, 'bms_max_temp_c': 55,
    'max_charge_voltage_v': 400, 'max_charge_current_a': 12, 'alt_charge_voltage_v': 380,
    'alt_charge_current_a': 6, 'sleep_delay_min': 5, 'mpi_function': 1, 'mpo1_function': 2,
    'mpo2_function': 3, 'parallel_strings': 1, 'enable_precharge': True,
    'stationary_mode': False, 'cells_per_module': [12, 12, 12, 12, 8] + [0] * 11,
    'reverse_current_display': False, 'night_brightness': 10,
}
# ZEVA's Monitor order (EVMS_Monitor3.c TransmitSettings): 36 first, then 32..35; the EVMS3
# saves to EEPROM when 35 arrives, so the cell counts must come before it.
EVMS3_FRAMES = [
    # module 2n in the low nibble of byte n
    (36, bytes([0xCC, 0xCC, 0x08, 0, 0, 0, 0, 0])),
    # capacity 5 Ah/bit, SoC warn, full 2 V/bit, warn/trip 10 A/bit, temp, aux, isolation
    (32, bytes([20, 20, 200, 20, 30, 60, 11, 50])),
    # tacho, gauges, min cell 1.50 + 0.01 n, max cell 2.00 + 0.01 n, balance 2.00 + 0.01 n
    (33, bytes([2, 90, 10, 80, 20, 130, 165, 150])),
    # hysteresis 0.01 V, temps n - 40, 400 V = 0x190: low 0x90 + bit 7 of 12 A; 380 V = 0x17C
    (34, bytes([5, 40, 95, 0x90, 0x80 | 12, 0x7C, 0x80 | 6, 5])),
    # MPI, MPO1, MPO2, strings, precharge, stationary, reverse current display, brightness 10
    (35, bytes([1, 2, 3, 1, 1, 0, 0, 10])),
]
IDLE, RUNNING, SETUP = 0, 2, 5


def evms3_params(enabled=True, config=EVMS3_CONFIG, skip=()):
    params = {'devices': ['evms3'], 'commands_allowed': True, 'commands_enabled': enabled,
              'evms3.stale_timeout': 3600.0}  # one status frame keeps its state known
    params.update({f'evms3.config.{k}': v for k, v in config.items() if k not in skip})
    return params


def evms3_status(bridge, state, error, b5=0x8C):
    """Put an EVMS3 status frame (ID 30) on the bus of a Rig or a Bench, as the EVMS would."""
    bridge.capture.bus.send(can.Message(arbitration_id=30, is_extended_id=True, data=bytes(
        [state | error << 3, 0x03, 0xE8, 0x0F, 0xA0, b5, 100, 65])))


def evms3_in(bridge, state, b5=0x8C):
    """Have the EVMS3 report state (0 IDLE, 5 SETUP, ...) and wait until the bridge knows."""
    evms3_status(bridge, state, 0, b5)
    device = bridge.devices['evms3']
    assert bridge.wait(lambda: device.state is not None and int(device.state) == state
                       and device.status.aux_voltage_v == b5 / 10)


# --- EVMS3 configuration (doc/protocols.md section 3; ZEVA's Monitor, EVMS_Monitor3.c) -------
# Written as frames 32..35 in test_protocol_evms3.py and read back on 52..56 below.
EVMS3_GOLDEN_CONFIG = Evms3Settings(
    pack_capacity_ah=100, soc_warning_pct=20, full_voltage_v=400, warn_current_a=300,
    trip_current_a=500, temp_warning_c=60, min_aux_voltage_v=11, min_isolation_pct=50,
    tacho_ppr=2, fuel_gauge_full_pct=90, fuel_gauge_empty_pct=10, temp_gauge_hot_pct=80,
    temp_gauge_cold_pct=20, bms_min_cell_v=2.8, bms_max_cell_v=3.65, balance_v=3.5,
    balance_mode='static', bms_hysteresis_v=0.05, bms_min_temp_c=0, bms_max_temp_c=55,
    max_charge_voltage_v=300, max_charge_current_a=30, alt_charge_voltage_v=250,
    alt_charge_current_a=10, sleep_delay_min=3, mpi_function=1, mpo1_function=2,
    mpo2_function=6, parallel_strings=2, enable_precharge=True, stationary_mode=False,
    reverse_current_display=True, night_brightness=7)

# The EVMS3's answer to ID 51 (ZEVA's open EVMS3 firmware, MIT, 2021): the bytes of the 32..35
# golden frames of test_protocol_evms3 (EVMS3_GOLDEN_CONFIG), now on 52..55:
EVMS3_ANSWER = {
    52: bytes.fromhex('14 14 C8 1E 32 3C 0B 32'),  # 100/5, 20, 400/2, 300/10, 500/10, 60 ..
    53: bytes.fromhex('02 5A 0A 50 14 82 A5 96'),  # .. 2.80 V = 1.50 + 1.30, 3.65, 3.50 V
    54: bytes.fromhex('05 28 5F 2C 9E FA 0A 03'),  # 300 V: 0x2C + 9th bit in 0x9E (30 A)
    # .. bytes 6-7: reverse current display 1, night brightness 7 (settings 30, 31)
    55: bytes.fromhex('01 02 06 02 01 00 01 07'),
    # module 0 = 12 (low nibble of byte 0), module 1 = 8, module 2 = 4, module 3 = 5,
    # module 15 = 12 (high nibble of byte 7)
    56: bytes.fromhex('8C 54 00 00 00 00 00 C0'),
}
EVMS3_ANSWER_CELLS = (12, 8, 4, 5) + (0,) * 11 + (12,)


# --- BMS16 standard form: written byte by byte from ZEVA's EVMS Monitor firmware -------------
# (soyachips/ZEVA_EVMS_Monitor_v3_FZR250, EVMS_Monitor3.c and Common.h; test_protocol_bms16_std)
# state RUNNING (2) | error LOW_SOC_WARNING (10) << 3 = 0x52; 123.4 Ah = 0x04D2;
# 52.8 V = 0x0210; byte 5 = 255 (BMS16 marker); byte 6 unused; 25 degC + 40 = 0x41
BMS16_STD_STATUS = bytes.fromhex('52 04 D2 02 10 FF 00 41')
# the same frame from an EVMS3: byte 5 = aux voltage 12.3 V (0x7B)
BMS16_STD_EVMS3_STATUS = bytes.fromhex('52 04 D2 02 10 7B 64 41')
BMS16_STD_CONFIG = {
    'pack_capacity_ah': 200,        # slot 0: x5 Ah -> 40 (0x28)
    'soc_warning_pct': 20,          # slot 1: 20 (0x14)
    'full_voltage_v': 58.0,         # slot 2: 1 V steps on a BMS16 -> 58 (0x3A)
    'warn_current_a': 150,          # slot 3: x10 A -> 15 (0x0F)
    'trip_current_a': 300,          # slot 4: x10 A -> 30 (0x1E); slot 5 unused: 0
    'cells': 14.0,                  # slot 6 (NUM_CELLS) -> 14 (0x0E)
    'shunt_size_a': 200,            # slot 7 (SHUNT_SIZE) -> code 2
    'min_cell_v': 2.8,              # slot 13: 1.50 + 0.01 n -> 130 (0x82)
    'max_cell_v': 3.65,             # slot 14: 2.00 + 0.01 n -> 165 (0xA5)
    'balance_mode': 'static',
    'balance_v': 3.45,              # slot 15: 2.00 + 0.01 n -> 145 (0x91)
    'hysteresis_v': 0.05,           # slot 16: 0.01 V -> 5
    'min_temp_c': 0,                # slot 17: n - 40 -> 40 (0x28)
    'max_temp_c': 55,               # slot 18: n - 40 -> 95 (0x5F)
    'max_charge_voltage_v': 57,     # slot 19: 57 (0x39)
    'max_charge_current_a': 20,     # slot 20: 20 (0x14); slots 21..28 unused: 0
    'stationary_mode': True,        # slot 29: 1
    'reverse_current_display': False,  # slot 30: 0
    'night_brightness': 3,          # slot 31: 3
}
BMS16_STD_WRITE = [
    (36, bytes.fromhex('68 00 00 00 00 00 00 00')),  # module 0: 8 cells, module 1: 14 - 8
    (32, bytes.fromhex('28 14 3A 0F 1E 00 0E 02')),
    (33, bytes.fromhex('00 00 00 00 00 82 A5 91')),
    (34, bytes.fromhex('05 28 5F 39 14 00 00 00')),
    (35, bytes.fromhex('00 00 00 00 00 01 00 03')),
]


# --- one set of hand-written frames per device type (doc/protocols.md) -----------------------
FRAMES = [
    Frame(0x521, bytes([0, 0]) + (-12_000).to_bytes(4, 'big', signed=True)),  # IVT-S -12 A
    Frame(0x300, bytes([0xC0, 0x21, 180, 30, 66, 1, 0])),  # AMS IDLE, SOC 66 %
    # EVMS3 ID 30: Running (2), 123.4 Ah, 345.6 V, 13.1 V aux, 99 % isolation, 25 degC
    Frame(30, bytes([0x02, 0x04, 0xD2, 0x0D, 0x80, 131, 99, 65]), True),
    Frame(500, bytes([0, 81, 0x0B, 0x02, 0x7D, 0x80, 25])),  # BMS16 SoC 81 %
    # SMA limits 55.2 / 48.0 V (they tell 0x356's 0.01 V), then 51.2 V -15.3 A
    Frame(0x351, bytes([0x28, 0x02, 0xF4, 0x01, 0xE8, 0x03, 0xE0, 0x01])),
    Frame(0x356, bytes([0x00, 0x14, 0x67, 0xFF, 0xE7, 0x00])),
]


def bms16_status(error: int, soc: int, volts_x10: int, amps_x10: int, temp: int) -> bytes:
    """ID 500: b0 error, b1 SoC, b2..3 0.1 V LE, b4..5 (raw-32768) 0.1 A LE, b6 degC."""
    return (bytes([error, soc]) + volts_x10.to_bytes(2, 'little')
            + (amps_x10 + 32768).to_bytes(2, 'little') + bytes([temp]))


# --- reading what a bridge published ----------------------------------------------------------
def values(status: Any) -> dict[str, str]:
    """Return a DiagnosticStatus's key/values as a dict."""
    return {kv.key: kv.value for kv in status.values}


def level(status: Any) -> int:
    """Return a DiagnosticStatus's level as an int (rclpy gives bytes)."""
    return status.level[0] if isinstance(status.level, bytes) else int(status.level)


BATTERY_FIELDS = ('voltage', 'current', 'percentage', 'temperature', 'power_supply_status',
                  'power_supply_health', 'present')


def published(report: Any) -> tuple:
    """Return what a BatteryState (or report) publishes: its fields as float32, its cells."""
    return (tuple(f32(getattr(report, k)) if isinstance(getattr(report, k), float)
                  else int(getattr(report, k)) for k in BATTERY_FIELDS)
            + (tuple(f32(v) for v in report.cell_voltage),))


def every_device() -> dict:
    """Return the params of a bridge with one instance of every device type."""
    return {'devices': list(registry.DEVICE_TYPES), 'pack.members': ['evms3', 'bms16'],
            **{f'dbc.{key}': value for key, value in OUR_PARAMS.items()}}


# --- the log2bag scenario: the demo's simulators written as a log, their parameters ---------
SECONDS = 6.0
BANKS = 2
DIAGNOSTICS_PERIOD = 0.5


def parameters() -> dict:
    """Return the bridge parameters of the demo's devices with BANKS AMS banks."""
    return {'devices': list(DEVICES), 'diagnostics_period': DIAGNOSTICS_PERIOD,
            **device_parameters(BANKS)}


def params_file(path: str) -> str:
    """Write parameters() as the bridge's nested ROS 2 parameters file."""
    tree: dict = {}
    for key, value in parameters().items():
        node = tree
        *parents, leaf = key.split('.')
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = value
    with open(path, 'w', encoding='utf-8') as stream:
        yaml.safe_dump({'/**': {'ros__parameters': tree}}, stream)
    return path


def copy_as(src: str, dst: str) -> str:
    """Rewrite a log in the format of dst's suffix (python-can's own writer)."""
    with can.LogReader(src) as reader, can.Logger(dst) as writer:
        for msg in reader:
            writer.on_message_received(msg)
    return dst


@functools.cache
def _typestore() -> Any:
    from rosbags.typesys import get_typestore, Stores
    return get_typestore(Stores.ROS2_JAZZY)


def rosbags_read(bag: str) -> dict[str, list]:
    """Return (bag time ns, message) per topic, read with rosbags."""
    from rosbags.highlevel import AnyReader
    out: dict[str, list] = {}
    with AnyReader([Path(bag)], default_typestore=_typestore()) as reader:
        for connection, t_ns, raw in reader.messages():
            out.setdefault(connection.topic, []).append(
                (t_ns, reader.deserialize(raw, connection.msgtype)))
    return out


# --- log2bag's own readers against python-can's path (test_log2bag_own_readers*.py) ---------

def frame_counts(frames: Any) -> tuple:
    """Return a LogFrames' counters: bad, last_bad, bad_stamps, stopped, truncated, cut_line."""
    return (frames.bad, frames.last_bad, frames.bad_stamps, frames.stopped, frames.truncated,
            frames.cut_line)


def read_both_ways(path: Any) -> tuple[list[str], tuple]:
    """
    Read a log with python-can (LogFrames iterated) and with ``LogFrames.frames()``.

    Assert the same frames (their ``repr``: the same types too) and counters; return them.
    """
    reference = LogFrames(str(path))
    want = [repr(message_frame(msg)) for msg in reference]
    reference.close()
    own = LogFrames(str(path))
    got = [repr(frame) for frame in own.frames()]
    own.close()
    for index, (mine, theirs) in enumerate(zip(got, want)):
        assert mine == theirs, f'{path}: frame {index}'
    assert len(got) == len(want)
    assert frame_counts(own) == frame_counts(reference)
    return got, frame_counts(own)


def bare_python_can(path: Any) -> list[str]:
    """Return the frames of a bare ``can.LogReader`` read, as ``read_both_ways`` gives them."""
    reader = can.LogReader(str(path))
    try:
        return [repr(message_frame(msg)) for msg in reader]
    finally:
        reader.stop()


# --- probe ---

def one_line_error(capsys, argv: list[str]) -> str:
    """Run probe; assert exit 2 with exactly one error line on stderr; return that line."""
    assert probe_main(argv) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.strip().splitlines()  # live: what it listened to first
             if not line.startswith('probe: listening on')]
    assert len(lines) == 1 and lines[0].startswith('probe: '), err
    assert 'Traceback' not in err
    return lines[0]


def traffic_of(frames: list[tuple[float, int, bytes]], extended: bool = False) -> Traffic:
    """Return probe's Traffic heard from (stamp, id, data) frames."""
    traffic = Traffic()
    for stamp, can_id, data in frames:
        traffic.add(can_id, extended, data, stamp)
    return traffic


def only(findings: Findings, kind: str):
    """Return the one device of type ``kind`` probe found; AssertionError if not exactly one."""
    found = [c for c in findings.devices if c.type == kind]
    assert len(found) == 1, [c.title for c in findings.devices]
    return found[0]
