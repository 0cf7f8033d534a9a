# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
IVT-S device side of the command services: the rows, the configuration wanted, the checks.

A mixin of ``IvtSDevice`` (devices/ivt_s/device.py): it uses the device's lock, configuration,
``link`` (the 0x511 answers, devices/ivt_s/exchanges.py) and result tracks. No rclpy; the
command pipeline (engine/commands.py) calls these methods with a ``send`` (its ``CallPort``)
that applies the gate and waits for the bus.
"""
from __future__ import annotations

from dataclasses import replace
import threading
from typing import Any, Callable, ClassVar, Iterable

from ams_can_bridge.devices.ivt_s import exchanges as seq
from ams_can_bridge.devices.commands import Command, EXCHANGE, SET_BOOL, TRIGGER
from ams_can_bridge.devices.generated_configs import IvtSConfig
from ams_can_bridge.devices.ivt_s.exchanges import config_problems, NoAnswer
from ams_can_bridge.devices.ports import SendFrame
from ams_can_bridge.errors import RefusedCommand
from ams_can_bridge.protocols.ivt_s import DBC_NAME, IvtMux
from ams_can_bridge.protocols.ivt_s_commands import (
    CYCLE_MAX_MS, DISABLED_CYCLE_MS, ResultConfig, TriggerMode)

# The config.<result>_cycle_ms parameter of each result (DBC result names, lower case).
CYCLE_KEYS = {kind: f'config.{DBC_NAME[kind].lower()}_cycle_ms' for kind in IvtMux}
ERROR_MASKS_KEY = 'config.error_masks'  # byte 1 bit 5 of every result (global); unset: kept


def _whole_ms(value: Any) -> int | None:
    """Return a cycle time as int (3 and 3.0 alike), None if it is no whole number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value):
        return None
    return int(value)


class IvtSControl:
    """read_config, write_config, set_running, restart, reset_errors of one IVT-S."""

    # Each runs its exchange (0x411 -> 0x511) through the pipeline's port (devices/commands.py)
    COMMANDS: ClassVar[tuple[Command, ...]] = (
        Command('read_config', 'read the configuration', TRIGGER, 'read_config', EXCHANGE),
        Command('write_config', 'write the configuration', TRIGGER, 'write_config', EXCHANGE),
        Command('restart', 'restart the sensor', TRIGGER, 'restart', EXCHANGE),
        Command('reset_errors', 'reset the errors', TRIGGER, 'reset_errors', EXCHANGE),
        Command('set_running', 'run the sensor', SET_BOOL, 'set_running', EXCHANGE,
                what_false='stop the sensor'),
    )

    name: str
    config: IvtSConfig
    lock: threading.Lock
    link: seq.CommandLink
    byte_order: str
    discharge_positive: bool
    mounted_reversed: bool
    _tracks: dict
    clock: Callable[[], float]

    def config_problems(self, config: IvtSConfig,
                        keys: Iterable[str] | None = None) -> list[str]:
        """Name every config.<result>_cycle_ms that is not a whole 0..65535 ms."""
        wanted = CYCLE_KEYS.values() if keys is None else [
            k for k in keys if k in CYCLE_KEYS.values()]
        problems = []
        for key in wanted:
            value = config.value(key)
            if value is None:
                continue
            ms = _whole_ms(value)
            if ms is None or not 0 <= ms <= CYCLE_MAX_MS:
                problems.append(f'{self.name}.{key} = {value!r} refused: allowed a whole '
                                f'number of ms 0..{CYCLE_MAX_MS} (0 = off)')
        return problems

    def _config_problems(self) -> list[str]:
        """Mismatches between the last read-back and the parameters (lock held)."""
        read = self.link.read_back
        if read is None:
            return []
        return config_problems(read.configs, self.name, self.byte_order,
                               self.discharge_positive, self.mounted_reversed)

    def _command_values(self) -> dict[str, str]:
        link, now = self.link, self.clock()
        values = {'answers (0x511)': str(link.answers)}
        if link.mode is not None:
            values['sensor mode'] = ('RUN' if link.mode.running else 'STOP') + (
                ', after power-up ' + ('RUN' if link.mode.startup_running else 'STOP'))
        read = link.read_back
        if read is None:
            values['config check'] = 'not read (read_config)'
        else:
            problems = self._config_problems()
            values['config check'] = (f'{"; ".join(problems) or "ok"} (read '
                                      f'{now - link.read_at:.0f} s ago)')
        for kind, config in sorted(link.configs.items()):
            values[f'{DBC_NAME[kind]} config'] = config.text()
        if link.last_error is not None:
            values['last error item'] = link.last_error.text()
        if link.alive is not None:
            values['alive after restart'] = (
                f'{link.alive_count} time(s), last {now - link.alive_at:.1f} s ago, serial '
                f'{link.alive.serial}')
        if link.wrong is not None:
            values['wrong command answers'] = (
                f'{link.wrong_count}, last for command 0x{link.wrong.command:02X}')
        if link.other is not None:
            values['unknown answers'] = (f'{link.other_count}, last '
                                         f'{link.other.data.hex(" ").upper()}')
        return values

    def start_command(self) -> str | None:
        """check_config_at_start: read_config once, when heard while commands are enabled."""
        return 'read_config' if self.config.check_config_at_start else None

    def heard(self) -> bool:
        """Tell whether any result frame came (check_config_at_start waits for it)."""
        with self.lock:
            return bool(self._tracks)

    def wanted_configs(self) -> list[ResultConfig]:
        """Return the configuration write_config sends (RefusedCommand while one is unset)."""
        config = self.config
        missing = [f'{self.name}.{key}' for key in CYCLE_KEYS.values()
                   if config.value(key) is None]
        if missing:
            raise RefusedCommand(f'{len(missing)} value(s) unset: ' + ', '.join(missing)
                                 + ' (cycle time in ms, 0 = off)')
        inverted = (not self.discharge_positive) != self.mounted_reversed
        wanted = []
        for kind, key in CYCLE_KEYS.items():
            cycle = _whole_ms(config.value(key))
            if cycle is None or not 0 <= cycle <= CYCLE_MAX_MS:
                raise RefusedCommand(f'{self.name}.{key} = {config.value(key)!r}: allowed '
                                     f'0..{CYCLE_MAX_MS}')
            wanted.append(ResultConfig(
                kind, TriggerMode.CYCLIC if cycle else TriggerMode.DISABLED,
                cycle or DISABLED_CYCLE_MS, self.byte_order == 'little',
                inverted and kind in seq.DIRECTIONAL, bool(config.value(ERROR_MASKS_KEY))))
        return wanted

    def _timeout_s(self) -> float:
        return float(self.config.command_timeout or 2.0)

    def _run(self, what: str, body: Callable[[], str]) -> tuple[bool, str]:
        if not self.link.begin():
            return False, f'{self.name}: cannot {what}: another IVT-S command is running'
        try:
            return True, f'{self.name}: {body()}'
        except NoAnswer as exc:
            return False, f'{self.name}: {what} failed: {exc}'
        finally:
            self.link.end()

    def read_config(self, send: SendFrame) -> tuple[bool, str]:
        """Read mode and configuration; (False, why) on no answer or a mismatch."""
        problems: list[str] = []

        def body() -> str:
            read = seq.read_config(self.link, send, self._timeout_s(), self.clock())
            with self.lock:
                problems.extend(self._config_problems())
            return 'read_config: ' + read.summary() + (
                '; MISMATCH: ' + '; '.join(problems) if problems else '; matches the bridge')
        ok, message = self._run('read the configuration', body)
        return ok and not problems, message

    def write_config(self, send: SendFrame) -> tuple[bool, str]:
        """
        Stop, write, store, run, read back and compare; refuse unset cycle times first.

        With config.error_masks unset the sensor's bit 5 is asked first (0x60) and kept.
        """
        try:
            wanted = self.wanted_configs()
        except RefusedCommand as exc:
            return False, f'{self.name}: write_config refused: {exc}; nothing was sent'

        keep_masks = self.config.value(ERROR_MASKS_KEY) is None

        def body() -> str:
            configs = wanted
            if keep_masks:  # bit 5 is global: the I result's answer shows the sensor's
                masks = seq.read_result(self.link, send, IvtMux.I, self._timeout_s())
                configs = [replace(c, error_masks=masks.error_masks) for c in wanted]
            steps = seq.write_config(self.link, send, configs, self._timeout_s())
            read = seq.read_config(self.link, send, self._timeout_s(), self.clock())
            differ = [DBC_NAME[c.kind] for c in configs if read.configs[c.kind] != c]
            if differ:
                raise NoAnswer(f'{", ".join(steps)}, but the read-back differs for '
                               f'{", ".join(differ)}: {read.summary()}')
            return f'write_config: {", ".join(steps)}; read back: {read.summary()}'
        return self._run('write the configuration', body)

    def set_running(self, send: SendFrame, running: bool) -> tuple[bool, str]:
        """Run or stop the sensor now (0x34); the answer says the mode it reports."""
        what = 'run' if running else 'stop'

        def body() -> str:
            mode = seq.set_running(self.link, send, running, self._timeout_s())
            if mode.running != running:
                raise NoAnswer(f'the sensor answered but reports '
                               f'{"RUN" if mode.running else "STOP"}')
            return f'set_running: the sensor reports {"RUN" if mode.running else "STOP"}'
        return self._run(what, body)

    def restart(self, send: SendFrame) -> tuple[bool, str]:
        """Restart the sensor (0x3F) and wait for its alive message (0xBF)."""
        def body() -> str:
            alive = seq.restart(self.link, send, self._timeout_s())
            return f'restart: alive again (serial {alive.serial}); the As and Wh counters ' \
                   'start from 0'
        return self._run('restart', body)

    def reset_errors(self, send: SendFrame) -> tuple[bool, str]:
        """Stop, reset all measurement and system errors (0x30, with the serial number), run."""
        def body() -> str:
            serial, steps = seq.reset_errors(self.link, send, self._timeout_s())
            return f'reset_errors: {", ".join(steps)} (serial {serial})'
        return self._run('reset the errors', body)
