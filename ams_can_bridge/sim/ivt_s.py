# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Simulated IVT-S shunt: all eight results every period, with consistent physics.

Pack side (positive = discharge, whatever the mounting): current from ``current_fn(now)``,
voltage from ``voltage_fn()`` (default: 400 V open circuit minus 50 mOhm x current),
charge = integral of current, energy = integral of U x I, temperature warming with I^2.
On the wire everything with a direction (I, W, As, Wh) carries the mounting sign: the
sensor measures current one way, and power / charge / energy follow from that current.

Commands on 0x411 are answered on 0x511 as doc/protocols.md section 2 describes: RUN/STOP
(0x34, 0x74), each result's configuration (0x2n, 0x6n: trigger mode, cycle time, byte order
and sign, applied to the frames sent; changed only while stopped), STORE (0x32), restart
(0x3F: the stored configuration and start-up mode, As/Wh from 0, alive message 0xBF),
restore defaults (0x3D), serial number (0x7B), error items (0x40, 0x41) and reset (0x30,
carried out only while stopped, answered either way, as the sensor does). Any other command
is answered "wrong command" (0xFF).
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, Mapping

from ams_can_bridge.protocols import ivt_s_commands as cmd
from ams_can_bridge.errors import ProtocolError
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.ivt_s import (
    COMMAND_ID, DEFAULT_BASE_ID, DIVISOR, INT32_MAX, INT32_MIN, IvtMux, IvtResult, IvtSCodec)
from ams_can_bridge.protocols.ivt_s_commands import (
    AliveAnswer, ErrorAnswer, IvtAnswer, ModeAnswer, ResetAnswer, ResultConfig, SerialAnswer,
    StoreAnswer, TriggerMode, WrongCommand)
from ams_can_bridge.sim.base import Periodic, SimDevice
from ams_can_bridge.sim.pack import Elapsed, thermal_lag
from ams_can_bridge.sim.profiles import drive_current_a

AMBIENT_C = 25.0
HEATING_C_PER_A2 = 0.0008  # steady-state rise: 120 A -> about +11.5 degC
RESTART_S = 0.05  # the simulated sensor is back (alive message) this long after 0x3F
# The result counters count measurement cycles of 20 ms, not frames: a real sensor's results
# sent every 100 ms advance theirs by 5 (foxBMS 2 tools/dbc/test_log.txt), a 20 ms result's
# by 1 (doc/protocols.md 2.1).
COUNTER_CYCLE_MS = 20
SERIAL = 0x00012345
# The commands 0x34 and 0x30 share the layouts of their answers 0xB4 and 0xB0 (the vendor
# DBC's _34_* / _30_* signals): decoded by the protocol's layouts, not by hand here.
_MODE = cmd.MODE.decoder('Actual_Mode', 'Startup_Mode')  # -> (running, startup_running)
_RESET = cmd.RESET.decoder('Reset_Item', 'Reset_Device_SN')  # -> (item, serial)
_ERROR_ITEM = cmd.ERROR.decoder('Error_Item')  # -> (item,): 0x40 / 0x41 b1, as in 0x80 / 0x81


def counter_step(config: ResultConfig) -> int:
    """
    Return how far a result's counter advances per frame: its cycle in 20 ms cycles.

    A cycle that is no whole number of them (unknown on a real sensor) advances by the
    nearest whole number, at least 1.
    """
    return max(1, round(config.cycle_ms / COUNTER_CYCLE_MS))


class IvtSSimulator(SimDevice):
    """
    IVT-S model for the simulator, the demo, tests and benchmarks.

    Faults honoured: silent, malformed (wrong DLC), error_code (any value: system error
    bit), extra['ocs'] (OCS bit), extra['result_error'] / extra['measurement_error'] (those
    bits on every result), extra['stuck_counter'] (counters stop advancing),
    extra['mute_commands'] (commands are taken but never answered).

    ``byte_order``, ``period`` and ``cycles_ms`` are this sensor's factory setting: every
    result cyclic at ``period`` unless ``cycles_ms`` gives it its own cycle (0: off), sign
    normal (``configs`` holds the configuration in use, ``stored`` the one a restart loads).
    """

    TYPE = 'ivt_s'

    def __init__(self, name: str | None = None, base_id: int = DEFAULT_BASE_ID,
                 byte_order: str = 'big', discharge_positive: bool = True,
                 current_fn: Callable[[float], float] | None = None,
                 voltage_fn: Callable[[], float] | None = None,
                 period: float = 0.1, cycles_ms: Mapping[IvtMux, int] | None = None) -> None:
        super().__init__(name)
        self.codec = IvtSCodec(base_id, byte_order)
        self.discharge_positive = discharge_positive
        self.current_fn = current_fn or drive_current_a
        self.voltage_fn = voltage_fn
        self.open_circuit_v = 400.0
        self.internal_resistance_ohm = 0.05
        self.period = period
        # cycles_ms: results set apart from the factory's ``period`` (0 = the result is off)
        cycles = {kind: round(period * 1000) for kind in IvtMux} | dict(cycles_ms or {})
        self.factory = {kind: ResultConfig(
            kind, TriggerMode.CYCLIC if cycles[kind] else TriggerMode.DISABLED,
            cycles[kind] or cmd.DISABLED_CYCLE_MS, byte_order == 'little') for kind in IvtMux}
        self.configs = dict(self.factory)
        self.stored = dict(self.factory)
        self.running = True
        self.startup_running = True
        self.serial = SERIAL
        self.received: list[tuple[int, bytes]] = []  # every command (mux, data), in order
        self.malformed_received = 0
        self._codecs = {order: IvtSCodec(base_id, order) for order in ('big', 'little')}
        self._periodic = {kind: Periodic(c.cycle_ms / 1000.0) for kind, c in self.factory.items()}
        self._answers: list[tuple[float, Frame]] = []  # (due time, 0x511 frame)
        self._restart_until: float | None = None
        self._counters = [0] * len(IvtMux)
        self._elapsed = Elapsed()
        # Pack-side state, positive = discharge.
        self.current_a = 0.0
        self.voltage_v = self.open_circuit_v
        self.power_w = 0.0
        self.charge_as = 0.0
        self.energy_wh = 0.0
        self.temperature_c = AMBIENT_C

    def _step(self, now: float) -> None:
        dt = self._elapsed(now)
        self.current_a = float(self.current_fn(now))
        self.voltage_v = (float(self.voltage_fn()) if self.voltage_fn is not None else
                          self.open_circuit_v - self.internal_resistance_ohm * self.current_a)
        self.power_w = self.voltage_v * self.current_a
        # Rectangle rule on the sample just taken: the same sum a receiver can form from
        # the frames (I_k x dt_k), so tests can check the integration exactly.
        self.charge_as += self.current_a * dt
        self.energy_wh += self.power_w * dt / 3600.0
        target = AMBIENT_C + HEATING_C_PER_A2 * self.current_a ** 2
        self.temperature_c = thermal_lag(self.temperature_c, target, dt)

    def wire_values(self) -> dict[IvtMux, float]:
        """Return the SI values as the sensor reports them (mounting sign applied)."""
        sign = 1.0 if self.discharge_positive else -1.0
        return {
            IvtMux.I: sign * self.current_a,
            IvtMux.U1: self.voltage_v,
            IvtMux.U2: self.voltage_v,  # measured after the contactors: closed here
            IvtMux.U3: 0.0,  # unused input
            IvtMux.T: self.temperature_c,
            IvtMux.W: sign * self.power_w,
            IvtMux.AS: sign * self.charge_as,
            IvtMux.WH: sign * self.energy_wh,
        }

    def tick(self, now: float) -> list[Frame]:
        """Frames due at ``now``: answers, then each result due on its own cycle."""
        frames = self._due_answers(now)
        if self._restart_until is not None:
            if now < self._restart_until:
                return frames
            self._restart_until = None
        due = [kind for kind in IvtMux if self.running
               and self.configs[kind].mode is TriggerMode.CYCLIC
               and self._periodic[kind].due(now)]
        if not due:
            return frames
        self._step(now)
        if self.faults.silent:
            return frames
        extra = self.faults.extra
        flags = dict(ocs=bool(extra.get('ocs')),
                     result_error=bool(extra.get('result_error')),
                     measurement_error=bool(extra.get('measurement_error')),
                     system_error=self.faults.error_code is not None)
        values = self.wire_values()
        for kind in due:
            config = self.configs[kind]
            value = -values[kind] if config.sign_inverted else values[kind]
            result = IvtResult.from_value(kind, value, counter=self._counters[kind], **flags)
            if not INT32_MIN <= result.raw <= INT32_MAX:  # saturate like a real sensor
                raw = INT32_MAX if result.raw > 0 else INT32_MIN
                result = IvtResult(kind, result.counter, result.ocs, True,
                                   result.measurement_error, result.system_error, raw,
                                   raw / DIVISOR[kind])
            if not extra.get('stuck_counter'):
                self._counters[kind] = (self._counters[kind] + counter_step(config)) & 0x0F
            frame = self._codecs[config.byte_order].encode(result)
            frames.append(self.corrupt(frame) if self.faults.malformed else frame)
        return frames

    # --- commands (0x411) and answers (0x511) ------------------------------------------------
    def _due_answers(self, now: float) -> list[Frame]:
        due = [frame for at, frame in self._answers if at <= now]
        self._answers = [(at, frame) for at, frame in self._answers if at > now]
        return [] if self.faults.silent else due

    def _answer(self, answer: IvtAnswer, at: float) -> None:
        if not self.faults.extra.get('mute_commands'):
            self._answers.append((at, cmd.encode_answer(answer)))

    def on_frame(self, frame: Frame, now: float) -> None:
        """Take a command on 0x411 (standard ID); ignore every other frame."""
        if frame.arbitration_id != COMMAND_ID or frame.is_extended_id:
            return
        try:
            mux, data = cmd.decode_command(frame.data)
        except ProtocolError:
            self.malformed_received += 1
            return
        self.received.append((mux, data))
        if self._restart_until is not None and now < self._restart_until:
            return  # restarting: deaf
        stopped = not self.running
        if cmd.SET_CONFIG_RESULT <= mux <= cmd.SET_CONFIG_RESULT + 7:
            try:
                wanted = cmd.decode_config(COMMAND_ID, data)
            except ProtocolError:
                self._answer(WrongCommand(mux), now)
                return
            kind = wanted.kind
            if stopped and wanted.cycle_ms:  # time 0 is ignored; RUN: no change
                self.configs[kind] = wanted
                self._periodic[kind] = Periodic(wanted.cycle_ms / 1000.0)
                # bit 5 is global: the last configuration written holds for every result
                self.configs = {k: dataclasses.replace(c, error_masks=wanted.error_masks)
                                for k, c in self.configs.items()}
            self._answer(self.configs[kind], now)
        elif cmd.GET_CONFIG_RESULT <= mux <= cmd.GET_CONFIG_RESULT + 7:
            self._answer(self.configs[IvtMux(mux - cmd.GET_CONFIG_RESULT)], now)
        elif mux == cmd.SET_MODE:
            self.running, self.startup_running = _MODE(data)
            self._answer(ModeAnswer(self.running, self.startup_running), now)
        elif mux == cmd.GET_MODE:
            self._answer(ModeAnswer(self.running, self.startup_running), now)
        elif mux == cmd.STORE:
            if stopped:
                self.stored = dict(self.configs)
            self._answer(StoreAnswer(), now)
        elif mux in (cmd.RESTART, cmd.RESTART_DEFAULT):
            if mux == cmd.RESTART_DEFAULT:
                self.stored = dict(self.factory)
            self._restart(now)
        elif mux == cmd.GET_SERIAL_NR:
            self._answer(SerialAnswer(self.serial), now)
        elif mux in (cmd.GET_MEAS_ERROR, cmd.GET_SYSTEM_ERROR):
            system = mux == cmd.GET_SYSTEM_ERROR
            active = (self.faults.error_code is not None if system
                      else bool(self.faults.extra.get('measurement_error')))
            (item,) = _ERROR_ITEM(data)
            self._answer(ErrorAnswer(system, item, int(active)), now)
        elif mux == cmd.RESET_ERR_LOG:  # Stop mode only; answered in RUN too (datasheet)
            item, serial = _RESET(data)
            if stopped and serial == self.serial:
                if item == cmd.RESET_ALL_SYSTEM_ERRORS:
                    self.faults.error_code = None
                elif item == cmd.RESET_ALL_MEASUREMENT_ERRORS:
                    self.faults.extra.pop('measurement_error', None)
            self._answer(ResetAnswer(item, self.serial), now)
        else:
            self._answer(WrongCommand(mux), now)

    def _restart(self, now: float) -> None:
        self.configs = dict(self.stored)
        self.running = self.startup_running
        self._periodic = {kind: Periodic(self.configs[kind].cycle_ms / 1000.0)
                          for kind in IvtMux}
        self._counters = [0] * len(IvtMux)
        self.charge_as = self.energy_wh = 0.0  # the counters start again after a restart
        self._answers.clear()
        self._restart_until = now + RESTART_S
        self._answer(AliveAnswer(COMMAND_ID, self.serial), self._restart_until)

    def misconfigure(self, **changes: Any) -> None:
        """Change every result's configuration in place (a sensor set up by another tool)."""
        self.configs = {k: dataclasses.replace(c, **changes) for k, c in self.configs.items()}
        self.stored = dict(self.configs)
