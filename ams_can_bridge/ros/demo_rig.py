"""
What the demo runs: simulated devices and the bridge on one virtual bus, and a view node.

``DemoRig`` owns the simulators, their SimRunner, the virtual bus and the bridge node;
``DemoMonitor`` is an ordinary ROS node that subscribes to the bridge's topics and turns the
latest messages into a ``demo_view.View``. Nothing in the view is read from the simulators
or the bridge object directly: the numbers took the same path as for any ROS subscriber.
"""
from __future__ import annotations

from functools import partial
import os
import threading
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState

from ams_can_bridge.ros.demo_view import cell_range, DeviceRow, level_name, View
from ams_can_bridge.registry import load, SIMULATORS
from ams_can_bridge.ros.bridge_node import BridgeNode, NODE_NAME

DEVICES = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma')
BMS12_MODULES = 2
PRECHARGE_S = 1.5
EVMS3_CAPACITY_AH = 100.0  # the SoC of the EVMS3 needs the pack capacity configured
# Keys of diagnostics values that hold a device's state or status name, best first.
STATE_KEYS = ('state', 'ams state', 'evms state', 'status')


def device_parameters(banks: int = 2) -> dict[str, Any]:
    """Return the bridge's device parameters that match the simulators (name.key: value)."""
    return {
        'ams.bank_count': banks,
        'ams.command_timeout': PRECHARGE_S + 3.0,
        'evms3.bms12_modules': BMS12_MODULES,
        'evms3.config.pack_capacity_ah': EVMS3_CAPACITY_AH,
    }


def _bridge_parameters(channel: str, banks: int, commands: bool,
                       extra: dict[str, Any] | None = None) -> list[Parameter]:
    """Return the bridge's parameters for the demo bus and devices (plus ``extra``)."""
    values: dict[str, Any] = {
        'can.interface': 'virtual',
        'can.channel': channel,
        'devices': list(DEVICES),
        'commands_allowed': commands,  # the demo arms itself: both keys at launch
        'commands_enabled': commands,
        'diagnostics_period': 0.25,  # the view redraws at 4 Hz: states keep up
        **device_parameters(banks),
        **(extra or {}),
    }
    return [Parameter(name, value=value) for name, value in values.items()]


def build_simulators(banks: int = 2, names: tuple[str, ...] = DEVICES) -> dict[str, Any]:
    """Build the simulated devices of the demo (or those of ``names``), keyed by name."""
    sims: dict[str, Any] = {}
    if 'ams' in names:
        # A precharge long enough to be seen in the view (a real one takes about a second).
        sims['ams'] = load(SIMULATORS['ams'])(name='ams', bank_count=banks,
                                              precharge_time=PRECHARGE_S)
    if 'ivt_s' in names:
        ams = sims.get('ams')
        sims['ivt_s'] = load(SIMULATORS['ivt_s'])(
            name='ivt_s', current_fn=ams.pack_current_a if ams else None,
            voltage_fn=ams.pack_voltage_v if ams else None)
    if 'evms3' in names:
        sims['evms3'] = load(SIMULATORS['evms3'])(
            name='evms3', bms12_modules=BMS12_MODULES, capacity_ah=EVMS3_CAPACITY_AH)
    if 'bms16' in names:
        # The SMA IDs are fixed (0x351..0x35F): a bus carries one SMA sender, and the BMS16
        # device reads them too. So the BMS16 is that sender and the 'sma' instance shows
        # the same pack through the SMA protocol; a second SMA pack would mix with it.
        sims['bms16'] = load(SIMULATORS['bms16'])(name='bms16', send_sma=True, seed=1)
    elif 'sma' in names:
        sims['sma'] = load(SIMULATORS['sma'])(name='sma', seed=2)
    return sims


class DemoRig:
    """The simulated devices, their runner and bus, and the bridge node, started together."""

    def __init__(self, banks: int = 2, commands: bool = True,
                 channel: str | None = None, misconfigured_ivt: bool = False,
                 context: Any = None) -> None:
        import can

        from ams_can_bridge.sim.runner import SimRunner
        self.channel = channel or f'ams_can_bridge_demo_{os.getpid()}_{id(self):x}'
        self.hardware_id = f'virtual:{self.channel}'
        self.simulators = build_simulators(banks)
        extra: dict[str, Any] = {}
        if misconfigured_ivt:
            # Set up little-endian by a vendor tool, while the bridge expects the factory
            # big-endian: check_config_at_start reads it and reports the mismatch.
            self.simulators['ivt_s'].misconfigure(little_endian=True)
            extra['ivt_s.check_config_at_start'] = True
        self.sim_bus = can.Bus(interface='virtual', channel=self.channel)
        self.runner = SimRunner(self.sim_bus, list(self.simulators.values()))
        try:
            self.bridge = BridgeNode(
                context=context,
                parameter_overrides=_bridge_parameters(self.channel, banks, commands, extra))
        except Exception:
            self.sim_bus.shutdown()
            raise
        self.runner.start()

    def silence(self, name: str) -> None:
        """Make one simulated device stop sending (fault injection)."""
        self.simulators[name].faults.silent = True

    def close(self) -> None:
        """Stop the simulators, destroy the bridge node (closes its bus), close our bus."""
        self.runner.stop()
        self.bridge.destroy_node()
        self.sim_bus.shutdown()


class DemoMonitor(Node):
    """Subscribe to the bridge's battery_state topics and /diagnostics; build the view."""

    def __init__(self, rig: DemoRig, node_name: str = 'ams_can_bridge_demo_view') -> None:
        super().__init__(node_name)
        self.rig = rig
        self.lock = threading.Lock()
        self.battery: dict[str, BatteryState] = {}
        self.diagnostics: dict[str, Any] = {}
        for name in DEVICES:
            self.create_subscription(
                BatteryState, f'{name}/battery_state',
                partial(self._on_battery, name), 10)
        self.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics, 10)

    def _on_battery(self, name: str, msg: BatteryState) -> None:
        with self.lock:
            self.battery[name] = msg

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        prefix = f'{NODE_NAME}: '
        with self.lock:
            for status in msg.status:
                if status.name.startswith(prefix):
                    self.diagnostics[status.name[len(prefix):]] = status

    def view(self, uptime: float, last: tuple[str, str]) -> View:
        """Return the view of the latest messages received."""
        with self.lock:
            battery = dict(self.battery)
            diagnostics = dict(self.diagnostics)
        view = View(bus=self.rig.hardware_id, uptime_s=uptime,
                    last_command=last[0], last_answer=last[1])
        bus = diagnostics.get('CAN bus')
        if bus is not None:
            values = {kv.key: kv.value for kv in bus.values}
            view.bus_state = values.get('state', bus.message)
            view.bus_level = level_name(bus.level)
            view.frames_in = _int(values.get('frames in'))
            view.frames_out = _int(values.get('frames out'))
        for name in DEVICES:
            view.rows.append(device_row(name, battery.get(name), diagnostics.get(name)))
        return view


def device_row(name: str, msg: BatteryState | None, status: Any) -> DeviceRow:
    """Build one device's row from its last BatteryState and DiagnosticStatus (either None)."""
    row = DeviceRow(name=name, type=name)
    values: dict[str, str] = {}
    if status is not None:
        values = {kv.key: kv.value for kv in status.values}
        row.level = level_name(status.level)
        row.message = status.message
        row.state = state_of(values, status.message, row.level)
    if msg is not None:
        row.voltage = msg.voltage
        row.current = msg.current
        row.percentage = msg.percentage
        row.temperature = msg.temperature
        row.cell_min, row.cell_max = cell_range(list(msg.cell_voltage))
    return row


def state_of(values: dict[str, str], message: str, level: str = '') -> str:
    """
    Return the state or status name a device reports, from its diagnostics.

    AMS and EVMS3 report a 'state' value; the others lead their message with their status
    ('OK', 'error LOW_CELL', 'alarms ...'); the IVT-S has no state: it is measuring.
    """
    for key, value in values.items():
        if key.lower() in STATE_KEYS and value:
            return value
    if level == 'STALE':
        return 'silent'
    head = message.split(';')[0].strip()
    if head[:1] in tuple('-+0123456789'):
        return 'measuring'
    return head if len(head) <= 16 else head[:15] + '.'


def _int(text: str | None) -> int | None:
    try:
        return int(text) if text is not None else None
    except ValueError:
        return None
