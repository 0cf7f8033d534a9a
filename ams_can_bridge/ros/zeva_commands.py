"""
ZEVA EVMS3 and BMS16 services: configuration read/write, setup mode, error acknowledge, SoC.

Every configuration value is a parameter ``<name>.config.<field>`` in physical units, without
a default: writing a guess would overwrite the device. ``write_config`` refuses until every
value is set and names all missing ones. The EVMS3 can report its configuration:
``read_config`` (the device sends ID 51 and joins the answer 52..56) sets every value from
it, so a write after it is a read-modify-write; it is refused unless ``<name>.config_request``
is true, because ID 51 is also a ZEVA motor controller's throttle frame.
Nothing is sent unless ``commands_enabled`` is true, and a refused call sends nothing: every
frame of a call is built (and so validated) before the first one is sent. Frames go through
the gate (``engine/gate.py``); the frames of one call go out in one ``gate.batch()``, so no
other call's frame lands between two of them.

A disarm (``commands_enabled`` false) during a multi-frame write wins at once: the gate lets
no further frame out, even of a sequence under way (nothing is ever sent after a disarm
returns). The call then answers which frames went out and which did not, and for the EVMS3
what that leaves in the device (``EVMS3_PARTIAL``).
"""
from __future__ import annotations

import time
from typing import Any, Callable, Iterable

from rclpy.parameter import Parameter
from std_srvs.srv import SetBool, Trigger

from ams_can_bridge.devices.bms16 import Bms16Device
from ams_can_bridge.devices.bms16_std import Bms16StdDevice
from ams_can_bridge.devices.evms3 import Evms3Device
from ams_can_bridge.engine.gate import CommandPort
from ams_can_bridge.errors import EncodeRangeError, RefusedCommand
from ams_can_bridge.protocols.common import Frame
from ams_can_bridge.ros.commander import Commander, DeviceT, ServiceHost


# doc/protocols.md 3.6: 32..36 change the EVMS3's RAM at once; only 35 saves to EEPROM.
EVMS3_PARTIAL = ('the EVMS3 saves its configuration to EEPROM only when ID 35 arrives, so the '
                 'frames sent changed its RAM only: it runs with them until its next power-up, '
                 'which restores the saved configuration; call write_config again (all five '
                 'frames) once commands are enabled')


def frame_text(frame: Frame) -> str:
    """Describe a frame as 'ID 32 (0x20) [01 02 ..]'."""
    data = frame.data.hex(' ').upper() or 'no data'
    return f'ID {frame.arbitration_id} (0x{frame.arbitration_id:X}) [{data}]'


class _ZevaCommands(Commander[DeviceT]):
    """Shared plumbing: the gate, all-or-nothing frame sequences, services."""

    def destroy(self) -> None:
        """Remove the services."""
        self._remove_services()

    # --- helpers -------------------------------------------------------------------------
    def _trigger(self, what: str, build: Callable[[], Iterable[Frame]]) -> Callable:
        """Make a Trigger callback that builds its frames, then sends them all in order."""
        def callback(request: Any, response: Any) -> Any:
            response.success, response.message = self._send_frames(what, build)
            return response
        return callback

    def _send_frames(self, what: str, build: Callable[[], Iterable[Frame]],
                     gap: float = 0.0, note_gap: bool = False,
                     partial: str = '') -> tuple[bool, str]:
        """Send a call's frames in one batch; ``partial``: what a sequence cut short means."""
        if not self.gate.enabled:
            return False, f'{self.name}: {self.gate.refusal(what)}'
        try:
            # Validation happens here, before anything is sent; a device builds a write from
            # one configuration object, so a parameter set meanwhile cannot mix two sets.
            # Only the deliberate refusals are answered here: anything else is a bug, which
            # the node logs with its traceback and answers as an internal error.
            frames = list(build())
        except (RefusedCommand, EncodeRangeError) as exc:
            return False, f'{self.name}: cannot {what}: {exc}; nothing was sent'
        sent: list[str] = []
        # A bus still opening (or reconnecting) is waited for once, before the first frame
        # and outside the batch, so calls wait side by side, not one after the other.
        ok, message = self.gate.wait_for_bus()
        if not ok:
            return False, f'{self.name}: cannot {what}: {message}; nothing was sent'
        with self.gate.batch():  # the pause after each frame too: nothing else lands there
            for k, frame in enumerate(frames):
                ok, message = self.gate.transmit(frame, wait=False)
                if not ok:
                    done = ', '.join(sent) if sent else 'nothing'
                    left = ', '.join(f'ID {f.arbitration_id}' for f in frames[k:])
                    after = f'. {partial}' if sent and partial else ''
                    return False, (f'{self.name}: {what} failed at {frame_text(frame)}: '
                                   f'{message}; sent before it: {done}; not sent: {left}'
                                   f'{after}')
                sent.append(frame_text(frame))
                if gap:
                    self._sleep(gap)  # after each frame, as the device's own tool paces it
        apart = f' ({gap * 1000:g} ms apart)' if note_gap else ''
        return True, f'{self.name}: {what}: sent ' + ', '.join(sent) + apart

    @staticmethod
    def _sleep(seconds: float) -> None:
        time.sleep(seconds)


class Evms3Commands(_ZevaCommands[Evms3Device]):
    """
    EVMS3: read_config (51 -> 52..56), write_config (36, 32..35), set_setup_mode (31), ...

    write_config sends as ZEVA's Monitor does (EVMS_Monitor3.c TransmitSettings): 36 first,
    then 32, 33, 34, 35, with WRITE_GAP after each frame; the EVMS3 saves to EEPROM when 35
    arrives. The device refuses it (nothing sent) unless the EVMS reports IDLE or SETUP.
    """

    WRITE_GAP = 0.02  # s: CanTX(..., 20) after each configuration frame in the Monitor

    def __init__(self, gate: CommandPort, device: Evms3Device, name: str,
                 host: ServiceHost) -> None:
        """Create the services of one EVMS3 instance."""
        super().__init__(gate, device, name, host)
        self._service(Trigger, 'write_config', self._write_config)
        self._service(SetBool, 'set_setup_mode', self._set_setup_mode)
        self._service(Trigger, 'acknowledge_error', self._trigger(
            'acknowledge the error', lambda: [device.ack_frame()]))
        self._service(Trigger, 'reset_soc', self._trigger(
            'reset the SoC', lambda: [device.reset_soc_frame()]))
        self._service(Trigger, 'read_config', self._read_config)

    def _write_config(self, request: Any, response: Any) -> Any:
        response.success, response.message = self._send_frames(
            'write the configuration', self.device.config_frames, gap=self.WRITE_GAP,
            partial=EVMS3_PARTIAL)
        return response

    def _read_config(self, request: Any, response: Any) -> Any:
        response.success, response.message = self._read()
        return response

    def _read(self) -> tuple[bool, str]:
        config = self.device.config
        if not config.config_request:
            return False, (
                f'{self.name}: read_config refused: {self.name}.config_request is false. ID 51 '
                'asks the EVMS3 for its configuration, but a ZEVA motor controller takes ID 51 '
                'as its throttle frame: set the parameter ' + self.name + '.config_request to '
                'true only if no ZEVA motor controller is on this bus; nothing was sent')
        if not self.gate.enabled:
            return False, f'{self.name}: {self.gate.refusal("read the configuration")}'
        # the gate waits for the bus outside its batch lock, then sends ID 51 under it
        result = self.device.read_config(self.gate.transmit, float(config.read_timeout or 2.0))
        readback = result.readback
        if readback is None or not result.ok:
            return False, f'{self.name}: read_config failed: {result.error}; nothing was set'
        values = readback.parameter_values()
        outcome = self.host.set_parameters_atomically([
            Parameter(f'{self.name}.config.{key}', value=value) for key, value in values.items()])
        if not outcome.successful:
            return False, (f'{self.name}: read_config: the EVMS3 answered, but its values '
                           f'cannot be set: {outcome.reason}; nothing was set')
        return True, (f'{self.name}: read_config: {readback.summary()}; set '
                      f'{len(values)} parameters {self.name}.config.*')

    def _set_setup_mode(self, request: Any, response: Any) -> Any:
        setup = bool(request.data)
        what = 'enter Setup mode' if setup else 'return to Idle'
        response.success, response.message = self._send_frames(
            what, lambda: [self.device.setup_mode_frame(setup)])
        return response


class Bms16Commands(_ZevaCommands[Bms16Device | Bms16StdDevice]):
    """
    BMS16: write_config, acknowledge_error, reset_soc, power_off.

    Variant inverter: 504, 505 / 506 / 507 / 508. Variant standard (EVMS3 protocol): IDs 36,
    32..35 with the device's pause after each (ZEVA's Monitor: 20 ms) / 37 / 38 / 39.
    """

    def __init__(self, gate: CommandPort, device: Bms16Device | Bms16StdDevice, name: str,
                 host: ServiceHost) -> None:
        """Create the services of one BMS16 instance (either variant)."""
        super().__init__(gate, device, name, host)
        gap = float(getattr(device, 'CONFIG_FRAME_GAP', 0.0))
        self._service(Trigger, 'write_config', self._paced_trigger(
            'write the configuration', device.config_frames, gap) if gap else self._trigger(
            'write the configuration', device.config_frames))
        self._service(Trigger, 'acknowledge_error', self._trigger(
            'acknowledge the error', lambda: [device.ack_frame()]))
        self._service(Trigger, 'reset_soc', self._trigger(
            'reset the SoC', lambda: [device.reset_soc_frame()]))
        self._service(Trigger, 'power_off', self._trigger(
            'power the BMS16 off', lambda: [device.power_off_frame()]))

    def _paced_trigger(self, what: str, build: Callable[[], Iterable[Frame]],
                       gap: float) -> Callable:
        """Make a Trigger callback that sends its frames in order, ``gap`` s after each."""
        def callback(request: Any, response: Any) -> Any:
            response.success, response.message = self._send_frames(what, build, gap, True)
            return response
        return callback
