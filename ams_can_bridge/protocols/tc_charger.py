# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
TC / Elcon chargers 1..3 as a ZEVA EVMS3 drives them (IDs, fields, decisions: doc/protocols.md 7).

``ChargerStatus.status`` is the raw status byte, so that bits the DBC does not name still warn.
The answer's output current is 15 bits and a direction: TC's protocol 1430 marks bit 15 of
bytes 2-3 "0: Charging, 1: Discharging" (a discharging charger is not 3286.8 A).
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, replace
from typing import Union

from ams_can_bridge.errors import EncodeRangeError, MalformedFrameError
from ams_can_bridge.protocols.common import check_dlc, Frame
from ams_can_bridge.protocols.layout import BadValue, Layout, LITTLE, Signal

TC_CHARGER1_RX_ID = 0x1806E5F4
TC_CHARGER1_TX_ID = 0x18FF50E5
TC_CHARGER2_RX_ID = 0x1806E7F4
TC_CHARGER2_TX_ID = 0x18FF50E7
TC_CHARGER3_RX_ID = 0x1806E8F4
TC_CHARGER3_TX_ID = 0x18FF50E8
CHARGERS = 3
COMMAND_IDS = (TC_CHARGER1_RX_ID, TC_CHARGER2_RX_ID, TC_CHARGER3_RX_ID)
STATUS_IDS = (TC_CHARGER1_TX_ID, TC_CHARGER2_TX_ID, TC_CHARGER3_TX_ID)
CHARGER_IDS = frozenset(COMMAND_IDS + STATUS_IDS)
DLC_RANGE = (5, 6, 7, 8)


class ChargerStatusBit(enum.IntFlag):
    """Status byte 4 of the charger's answer."""

    HARDWARE_FAILURE = 0x01
    OVER_TEMPERATURE = 0x02
    INPUT_VOLTAGE_ERROR = 0x04  # input (AC) voltage wrong or missing
    BATTERY_FAULT = 0x08  # reverse or not connected
    COMMUNICATION_TIMEOUT = 0x10  # no command from the EVMS in time


STATUS_BIT_TEXT = {
    ChargerStatusBit.HARDWARE_FAILURE: 'hardware failure',
    ChargerStatusBit.OVER_TEMPERATURE: 'over-temperature shutdown',
    ChargerStatusBit.INPUT_VOLTAGE_ERROR: 'input (AC) voltage error',
    ChargerStatusBit.BATTERY_FAULT: 'battery fault / no battery',
    ChargerStatusBit.COMMUNICATION_TIMEOUT: 'communication timeout',
}


@dataclass(frozen=True, slots=True)
class ChargerCommand:
    """EVMS -> charger 1..3: target voltage, current limit, stop (1) or charge (0)."""

    charger: int
    target_voltage_v: float
    current_limit_a: float
    stop: bool


@dataclass(frozen=True, slots=True)
class ChargerStatus:
    """
    Charger 1..3 -> bus: output voltage and current, raw status byte, raw temperature.

    output_current_a is positive while the charger charges, negative while it discharges
    (bit 15 of bytes 2-3 set).
    """

    charger: int
    output_voltage_v: float
    output_current_a: float
    status: int
    temperature_raw: int | None = None

    @property
    def active_bits(self) -> tuple[str, ...]:
        """Describe every set status bit, defined ones by name, in bit order."""
        return tuple(STATUS_BIT_TEXT[ChargerStatusBit(1 << b)] if 1 << b in STATUS_BIT_TEXT
                     else f'bit {b}' for b in range(8) if self.status >> b & 1)


ChargerReading = Union[ChargerCommand, ChargerStatus]


# The same bits for chargers 1..3 (msg_defs/evms3.dbc TC_Charger<n>_*, checked by
# evms3.check_dbc); big-endian (the default) but the single bytes from byte 4 on.
LAYOUTS = {
    'TC_Charger1_Command': Layout('TC_Charger1_Command', 8, (
        Signal('TargetVoltage', 7, 16, scale=0.1, unit='V', field='target_voltage_v'),
        Signal('CurrentLimit', 23, 16, scale=0.1, unit='A', field='current_limit_a'),
        Signal('ShutdownByBms', 32, 8, LITTLE, high=1, field='stop', lookup=(False, True),
               check='byte 4 = {value}, expected 0 (charge) or 1 (stop)')), divide=True),
    'TC_Charger1_Status': Layout('TC_Charger1_Status', 8, (
        Signal('OutputVoltage', 7, 16, scale=0.1, unit='V', field='output_voltage_v'),
        Signal('OutputCurrentDirection', 23, 1, field='discharging', flag=True),
        Signal('OutputCurrent', 22, 15, scale=0.1, unit='A', field='output_current_a')) + tuple(
        Signal(name, 32 + bit, 1, LITTLE) for bit, name in enumerate((
            'HardwareFailure', 'OverTemperature', 'InputVoltageError', 'BatteryFault',
            'CommunicationTimeout'))) + (Signal('Temperature', 40, 8, LITTLE),), divide=True),
}
_D_COMMAND = LAYOUTS['TC_Charger1_Command'].decoder()
_E_COMMAND = LAYOUTS['TC_Charger1_Command'].encoder()
# ChargerStatus as the wire carries it: the DBC's output voltage, current direction and
# magnitude, then the status byte and the temperature, both raw.
_STATUS = Layout('TC status', 6, LAYOUTS['TC_Charger1_Status'].signals[:3] + (
    Signal('Status', 32, 8, LITTLE, field='status'),
    Signal('Temperature', 40, 8, LITTLE, field='temperature_raw')), divide=True)
_D_STATUS = _STATUS.decoder()
_E_STATUS = _STATUS.encoder()


def _status(charger: int, data: bytes) -> ChargerStatus:
    voltage, discharging, current, status, temperature = _D_STATUS(data)
    return ChargerStatus(charger, voltage, -current if discharging else current, status,
                         temperature)


class TcChargerCodec:
    """Decode and encode the command and status frames of TC chargers 1..3."""

    is_extended_id = True
    arbitration_ids = CHARGER_IDS

    def decode(self, arbitration_id: int, data: bytes) -> ChargerReading:
        """Frame -> reading; MalformedFrameError for a foreign ID, DLC or value."""
        if arbitration_id not in CHARGER_IDS:
            raise MalformedFrameError(arbitration_id, data, 'not a TC charger ID')
        check_dlc(arbitration_id, data, DLC_RANGE)
        if arbitration_id in COMMAND_IDS:
            try:
                return ChargerCommand(COMMAND_IDS.index(arbitration_id) + 1, *_D_COMMAND(data))
            except BadValue as exc:  # byte 4 neither charge nor stop
                raise MalformedFrameError(arbitration_id, data, str(exc)) from None
        charger = STATUS_IDS.index(arbitration_id) + 1
        if len(data) == 5:  # no temperature sent
            return replace(_status(charger, bytes(data) + b'\x00'), temperature_raw=None)
        return _status(charger, data)

    def encode(self, message: ChargerReading) -> Frame:
        """Encode a reading as an 8-byte frame (reserved bytes 0); EncodeRangeError else."""
        if not isinstance(message, (ChargerCommand, ChargerStatus)):
            raise EncodeRangeError('message', message, 'a TC charger message')
        if isinstance(message.charger, bool) or message.charger not in range(1, CHARGERS + 1):
            raise EncodeRangeError('charger', message.charger, '1, 2 or 3')
        index = int(message.charger) - 1  # 2.0 is charger 2
        if isinstance(message, ChargerCommand):
            data = _E_COMMAND(message.target_voltage_v, message.current_limit_a,
                              1 if message.stop else 0)
            return Frame(COMMAND_IDS[index], data, True)
        temperature = message.temperature_raw  # None: not sent, DLC 5
        current = message.output_current_a
        discharging = isinstance(current, (int, float)) and current < 0
        data = _E_STATUS(message.output_voltage_v, discharging,
                         -current if discharging else current, message.status,
                         0 if temperature is None else temperature)
        return Frame(STATUS_IDS[index], data[:5] if temperature is None
                     else data + bytes(2), True)
