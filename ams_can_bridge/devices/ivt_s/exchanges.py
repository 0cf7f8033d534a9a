# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
IVT-S command exchanges: send one 0x411 command, wait for its 0x511 answer. No rclpy.

The sensor answers every defined command, even one it did not carry out (doc/protocols.md
section 2), so each step of a sequence waits for its own answer before the next command
goes out; that also keeps consecutive commands apart by more than the 2 ms the sensor needs.
The link keeps the last answers of each kind for the diagnostics, whoever asked.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from functools import partial
import threading
import time
from typing import Callable, Iterable

from ams_can_bridge.errors import AmsCanBridgeError
from ams_can_bridge.devices.ports import CANCEL_POLL, cancel_reason, SendFrame
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.protocols.ivt_s import DBC_NAME, IvtMux
from ams_can_bridge.protocols import ivt_s_commands as cmd
from ams_can_bridge.protocols.ivt_s_commands import (
    AliveAnswer, ErrorAnswer, IvtAnswer, ModeAnswer, OtherAnswer, ResetAnswer, ResultConfig,
    SerialAnswer, StoreAnswer, TriggerMode, WrongCommand)

# The results whose sign follows the current's direction (discharge_positive applies).
DIRECTIONAL = (IvtMux.I, IvtMux.W, IvtMux.AS, IvtMux.WH)
# s: at least this long for the STORE answer (the datasheet: up to about 1000 ms;
# sectioncritical/ivts waits 2 s after STORE, "plenty of time to complete the store
# operation"; doc/protocols.md section 2)
STORE_TIMEOUT = 2.0
# s: at least this long for each reset answer (the datasheet: 0x30 is answered at least
# +1200 ms after the command; doc/protocols.md section 2)
RESET_TIMEOUT = 1.5


class NoAnswer(AmsCanBridgeError):
    """A command was not sent, or its answer did not come in time (the reason is the text)."""


@dataclass(frozen=True)
class ReadBack:
    """One complete read of the sensor: its mode and every result's configuration."""

    mode: ModeAnswer
    configs: dict[IvtMux, ResultConfig]

    def summary(self) -> str:
        """Describe as 'RUN; I 10 ms, U1 60 ms, ...; big-endian; sign normal; error masks off'."""
        results = []
        for kind in IvtMux:
            config = self.configs[kind]
            results.append(f'{DBC_NAME[kind]} ' + (
                f'{config.cycle_ms} ms' if config.mode is TriggerMode.CYCLIC
                else 'off' if config.mode is TriggerMode.DISABLED else 'triggered'))
        mode = 'RUN' if self.mode.running else 'STOP'
        if self.mode.startup_running != self.mode.running:
            mode += f' (after power-up {"RUN" if self.mode.startup_running else "STOP"})'
        return '; '.join([mode, ', '.join(results),
                          _grouped(self.configs, lambda c: f'{c.byte_order}-endian'),
                          _grouped(self.configs, lambda c: 'sign inverted' if c.sign_inverted
                                   else 'sign normal'),
                          _grouped(self.configs, lambda c: 'error masks '
                                   + ('on' if c.error_masks else 'off'))])


def _grouped(configs: dict[IvtMux, ResultConfig], label: Callable[[ResultConfig], str]) -> str:
    groups: dict[str, list[str]] = {}
    for kind in IvtMux:
        groups.setdefault(label(configs[kind]), []).append(DBC_NAME[kind])
    if len(groups) == 1:
        return next(iter(groups))
    return ' / '.join(f'{text} ({", ".join(names)})' for text, names in groups.items())


def _names(kinds: Iterable[IvtMux]) -> str:
    return ', '.join(DBC_NAME[k] for k in kinds)


def config_problems(configs: dict[IvtMux, ResultConfig], instance: str, byte_order: str,
                    discharge_positive: bool, mounted_reversed: bool) -> list[str]:
    """
    Say where the sensor's configuration disagrees with the bridge's parameters.

    Each problem names the parameter to change. Results that are off are not checked: the
    bridge never decodes them.
    """
    active = {k: c for k, c in configs.items() if c.mode is not TriggerMode.DISABLED}
    problems = []
    orders = {c.byte_order for c in active.values()}
    if len(orders) > 1:
        little = [k for k, c in active.items() if c.little_endian]
        problems.append(f'the sensor sends {_names(little)} little-endian and the other results '
                        f'big-endian: one {instance}.byte_order cannot decode both; run '
                        f'{instance}/write_config')
    elif orders and orders != {byte_order}:
        [order] = orders
        problems.append(f'the sensor sends its results {order}-endian, {instance}.byte_order is '
                        f'{byte_order}: set {instance}.byte_order to {order} (or run '
                        f'{instance}/write_config)')
    # Sign inverted expected on the directional results when the bridge's convention and the
    # mounting disagree (doc/protocols.md section 2, "sign").
    want = (not discharge_positive) != mounted_reversed
    wrong = [k for k in DIRECTIONAL if k in active and active[k].sign_inverted != want]
    if wrong:
        sent = 'inverted' if not want else 'normal'
        implied = (sent == 'normal') != mounted_reversed
        problems.append(
            f'the sensor sends {_names(wrong)} with sign {sent}, so discharging current '
            f'arrives {"positive" if implied else "negative"} while {instance}.discharge_positive'
            f' is {str(discharge_positive).lower()}: set {instance}.discharge_positive to '
            f'{str(implied).lower()} (or {instance}.mounted_reversed, or run '
            f'{instance}/write_config)')
    negated = [k for k in IvtMux if k not in DIRECTIONAL and k in active
               and active[k].sign_inverted]
    if negated:
        problems.append(f'the sensor sends {_names(negated)} with sign inverted (negated '
                        f'values); no bridge parameter undoes that: run {instance}/write_config')
    return problems


class CommandLink:
    """The answers of one IVT-S; its lock is the device's (the bus thread offers under it)."""

    def __init__(self, lock: threading.Lock, command_id: int = 0x411) -> None:
        self._cv = threading.Condition(lock)
        self.command_id = command_id  # the protocol builds 0x411 frames: sent on this ID
        self._seq = 0
        self._recent: deque[tuple[int, IvtAnswer]] = deque(maxlen=64)
        self._busy = False
        self.answers = 0
        self.mode: ModeAnswer | None = None
        self.configs: dict[IvtMux, ResultConfig] = {}  # last answer per result (0xAn)
        self.read_back: ReadBack | None = None  # last complete read (read_config)
        self.read_at = 0.0
        self.last_error: ErrorAnswer | None = None
        self.alive: AliveAnswer | None = None
        self.alive_count = 0
        self.alive_at = 0.0
        self.wrong: WrongCommand | None = None
        self.wrong_count = 0
        self.other: OtherAnswer | None = None
        self.other_count = 0
        self.malformed = 0

    # --- bus thread (device lock held) ----------------------------------------------------
    def offer(self, answer: IvtAnswer, now: float) -> None:
        """Take one decoded 0x511 answer."""
        self.answers += 1
        self._seq += 1
        self._recent.append((self._seq, answer))
        if isinstance(answer, ResultConfig):
            self.configs[answer.kind] = answer
        elif isinstance(answer, ModeAnswer):
            self.mode = answer
        elif isinstance(answer, ErrorAnswer):
            self.last_error = answer
        elif isinstance(answer, AliveAnswer):
            self.alive, self.alive_at = answer, now
            self.alive_count += 1
        elif isinstance(answer, WrongCommand):
            self.wrong = answer
            self.wrong_count += 1
        elif isinstance(answer, OtherAnswer):
            self.other = answer
            self.other_count += 1
        self._cv.notify_all()

    # --- service threads (device lock NOT held) --------------------------------------------
    def begin(self) -> bool:
        """Reserve the link for one sequence (False: another one runs)."""
        with self._cv:
            if self._busy:
                return False
            self._busy = True
            return True

    def end(self) -> None:
        """Release the link after a sequence."""
        with self._cv:
            self._busy = False

    def remember(self, read: ReadBack, now: float) -> None:
        """Keep a complete read (the diagnostics check the parameters against it)."""
        with self._cv:
            self.read_back, self.read_at = read, now

    def exchange(self, send: SendFrame, frame: Frame, match: Callable[[IvtAnswer], bool],
                 what: str, timeout: float) -> IvtAnswer:
        """Send one command and return its answer; NoAnswer saying why not."""
        if frame.arbitration_id != self.command_id:
            frame = Frame(self.command_id, frame.data, frame.is_extended_id)
        with self._cv:
            start = self._seq
        ok, why = send(frame)
        if not ok:
            raise NoAnswer(f'{what} (0x{frame.data[0]:02X}) was not sent: {why}')
        deadline = time.monotonic() + timeout
        with self._cv:
            while True:
                for seq, answer in self._recent:
                    if seq > start and match(answer):
                        return answer
                    if seq > start and isinstance(answer, WrongCommand) \
                            and answer.command == frame.data[0]:
                        raise NoAnswer(f'the sensor refused {what} (0x{frame.data[0]:02X}): '
                                       'wrong command (0xFF)')
                left = deadline - time.monotonic()
                if left <= 0:
                    raise NoAnswer(f'no answer to {what} (0x{frame.data[0]:02X}) within '
                                   f'{timeout:g} s')
                ended = cancel_reason(send)
                if ended:
                    raise NoAnswer(f'ended while waiting for the answer to {what} '
                                   f'(0x{frame.data[0]:02X}): cancelled by {ended}')
                self._cv.wait(min(left, CANCEL_POLL))


# --- sequences (service threads) ------------------------------------------------------------
def is_mode(answer: IvtAnswer) -> bool:
    """Match a 0xB4 answer."""
    return isinstance(answer, ModeAnswer)


def is_config(kind: IvtMux) -> Callable[[IvtAnswer], bool]:
    """Match the 0xAn answer of one result."""
    return lambda answer: isinstance(answer, ResultConfig) and answer.kind == kind


def read_result(link: CommandLink, send: SendFrame, kind: IvtMux,
                timeout: float) -> ResultConfig:
    """Ask for one result's configuration (0x6n, answer 0xAn)."""
    return link.exchange(send, cmd.get_config(kind), is_config(kind),  # type: ignore
                         f'get the {DBC_NAME[kind]} configuration', timeout)


def read_config(link: CommandLink, send: SendFrame, timeout: float, now: float) -> ReadBack:
    """Ask for the mode (0x74) and each result's configuration (0x60..0x67)."""
    mode = link.exchange(send, cmd.get_mode(), is_mode, 'GET_MODE', timeout)
    configs = {kind: read_result(link, send, kind, timeout) for kind in IvtMux}
    read = ReadBack(mode, configs)  # type: ignore[arg-type]
    link.remember(read, now)
    return read


def while_stopped(link: CommandLink, send: SendFrame, timeout: float,
                  body: Callable[[list[str]], None]) -> list[str]:
    """
    Stop (0x34 00 01), run ``body`` (it appends its steps), run again (0x34 01 01).

    Returns the steps done. Raises NoAnswer naming the step that failed; once the sensor
    reported STOP it is first put back into RUN, and the text says whether that worked.
    """
    done: list[str] = []
    stopped = False
    try:
        mode = link.exchange(send, cmd.set_mode(False), is_mode, 'stop (SET_MODE)', timeout)
        if mode.running:  # type: ignore[union-attr]
            raise NoAnswer('the sensor answered stop (0x34) but stays in RUN')
        stopped = True
        done.append('stopped')
        body(done)
        mode = link.exchange(send, cmd.set_mode(True), is_mode, 'run (SET_MODE)', timeout)
        if not mode.running:  # type: ignore[union-attr]
            raise NoAnswer('the sensor answered run (0x34) but stays in STOP')
        stopped = False
        done.append('running')
        return done
    except NoAnswer as exc:
        if stopped:
            try:
                link.exchange(send, cmd.set_mode(True), is_mode, 'run (SET_MODE)', timeout)
                tail = 'the sensor was put back into RUN'
            except NoAnswer as again:
                tail = f'putting it back into RUN failed too ({again}): it may stay stopped'
            raise NoAnswer(f'{exc}; done before: {", ".join(done)}; {tail}') from None
        raise NoAnswer(f'{exc}; done before: {", ".join(done) or "nothing"}') from None


def write_config(link: CommandLink, send: SendFrame, wanted: list[ResultConfig],
                 timeout: float) -> list[str]:
    """
    Stop, write each result (0x2n), store (0x32), run: return the steps done.

    The sensor takes a configuration and STORE only in STOP (doc/protocols.md section 2).
    Raises NoAnswer naming the step that failed (see ``while_stopped``).
    """
    def body(done: list[str]) -> None:
        for config in wanted:
            echo = link.exchange(send, cmd.set_config(config), is_config(config.kind),
                                 f'set the {DBC_NAME[config.kind]} configuration', timeout)
            if echo != config:
                raise NoAnswer(f'the sensor answered the {DBC_NAME[config.kind]} '
                               f'configuration with "{echo.text()}" instead of '  # type: ignore
                               f'"{config.text()}"')
        done.append(f'wrote {len(wanted)} results')
        link.exchange(send, cmd.store(), lambda a: isinstance(a, StoreAnswer), 'STORE',
                      max(timeout, STORE_TIMEOUT))
        done.append('stored')
    return while_stopped(link, send, timeout, body)


def set_running(link: CommandLink, send: SendFrame, running: bool, timeout: float) -> ModeAnswer:
    """Run or stop now (0x34, after power-up RUN as before); return the sensor's answer."""
    answer = link.exchange(send, cmd.set_mode(running), is_mode,
                           'run' if running else 'stop', timeout)
    return answer  # type: ignore[return-value]


def restart(link: CommandLink, send: SendFrame, timeout: float) -> AliveAnswer:
    """Restart (0x3F) and wait for the alive message (0xBF)."""
    return link.exchange(send, cmd.restart(), lambda a: isinstance(a, AliveAnswer),
                         'RESTART', timeout)  # type: ignore[return-value]


def _is_reset_answer(item: int, answer: IvtAnswer) -> bool:
    return isinstance(answer, ResetAnswer) and answer.item == item


def reset_errors(link: CommandLink, send: SendFrame, timeout: float) -> tuple[int, list[str]]:
    """
    Read the serial number (0x7B); stop, reset all measurement and system errors (0x30), run.

    The sensor resets only in STOP and answers 0x30 in RUN too, resetting nothing
    (doc/protocols.md section 2): hence the stop. Each answer (0xB0) must name the item and
    the serial number sent. Returns the serial number and the steps done; raises NoAnswer
    as ``while_stopped`` does.
    """
    serial = link.exchange(send, cmd.get_serial(), lambda a: isinstance(a, SerialAnswer),
                           'GET_SERIAL_NR', timeout).serial  # type: ignore[union-attr]

    def body(done: list[str]) -> None:
        for item, what in ((cmd.RESET_ALL_MEASUREMENT_ERRORS, 'reset all measurement errors'),
                           (cmd.RESET_ALL_SYSTEM_ERRORS, 'reset all system errors')):
            answer = link.exchange(send, cmd.reset_errors(item, serial),
                                   partial(_is_reset_answer, item), what,
                                   max(timeout, RESET_TIMEOUT))
            if answer.serial != serial:  # type: ignore[union-attr]
                raise NoAnswer(f'the sensor answered {what} (0x30) for serial '
                               f'{answer.serial}, not {serial}')  # type: ignore[union-attr]
            done.append(what)
    return serial, while_stopped(link, send, timeout, body)
