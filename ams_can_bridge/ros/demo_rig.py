# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What the demo runs: simulated devices and the bridge on one virtual bus.

``DemoRig`` owns the simulators, their SimRunner, the virtual bus and the bridge node. The
demo's view comes from ``watcher.BridgeWatcher``, the monitor's node: nothing in it is read
from the simulators or the bridge object directly, the numbers took the same path as for any
ROS subscriber.
"""
from __future__ import annotations

import os
from typing import Any

from rclpy.parameter import Parameter

from ams_can_bridge.registry import load, SIMULATORS
from ams_can_bridge.ros.bridge_node import BridgeNode

DEVICES = ('ams', 'ivt_s', 'evms3', 'bms16', 'sma')
PACK_DEVICES = ('bms16', 'evms3', 'pack')  # demo --pack: config/pack.yaml's instances
BMS12_MODULES = 2
PRECHARGE_S = 1.5
EVMS3_CAPACITY_AH = 100.0  # the SoC of the EVMS3 needs the pack capacity configured


def device_parameters(banks: int = 2) -> dict[str, Any]:
    """Return the bridge's device parameters that match the simulators (name.key: value)."""
    return {
        'ams.bank_count': banks,
        'ams.command_timeout': PRECHARGE_S + 3.0,
        'evms3.bms12_modules': BMS12_MODULES,
        'evms3.config.pack_capacity_ah': EVMS3_CAPACITY_AH,
    }


def pack_parameters() -> dict[str, Any]:
    """Return config/pack.yaml's devices and their parameters (the installed example's)."""
    from ams_can_bridge.offline.params_file import load_parameters
    from ams_can_bridge.protocols.common import msg_defs_dir
    from ams_can_bridge.ros.bridge_node import NODE_NAME
    values = load_parameters(str(msg_defs_dir().parent / 'config' / 'pack.yaml'), NODE_NAME)
    # the bus, the keys and the diagnostics period are the demo's own
    node_keys = ('commands_allowed', 'commands_enabled', 'diagnostics_period')
    return {k: v for k, v in values.items() if not k.startswith('can.') and k not in node_keys}


def _bridge_parameters(channel: str, banks: int, commands: bool,
                       extra: dict[str, Any] | None = None,
                       devices: dict[str, Any] | None = None) -> list[Parameter]:
    """Return the bridge's parameters for the demo bus and devices (plus ``extra``)."""
    values: dict[str, Any] = {
        'can.interface': 'virtual',
        'can.channel': channel,
        'commands_allowed': commands,  # the demo arms itself: both keys at launch
        'commands_enabled': commands,
        'diagnostics_period': 0.25,  # the view redraws at 4 Hz: states keep up
        **(devices if devices is not None else {'devices': list(DEVICES),
                                                **device_parameters(banks)}),
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
                 context: Any = None, namespace: str = '',
                 pack: list[tuple[str, float]] | None = None) -> None:
        """
        Start the demo's devices, or with ``pack`` (scenarios, maybe none) config/pack.yaml's.

        The pack demo runs the simulator's pair (sim/pair.py) and its scenarios against the
        installed config/pack.yaml, as ``simulator --pack`` beside a bridge would.
        """
        import can

        from ams_can_bridge.sim.pair import build_pair, PairScenario
        from ams_can_bridge.sim.runner import SimRunner
        self.channel = channel or f'ams_can_bridge_demo_{os.getpid()}_{id(self):x}'
        self.hardware_id = f'virtual:{self.channel}'
        devices = None
        steering: list[Any] = []
        if pack is not None:
            pair = build_pair()
            self.simulators: dict[str, Any] = {sim.name: sim for sim in pair}
            steering = [PairScenario(pair, pack)] if pack else []
            devices = pack_parameters()
        else:
            self.simulators = build_simulators(banks)
        extra: dict[str, Any] = {}
        if misconfigured_ivt:
            # Set up little-endian by a vendor tool, while the bridge expects the factory
            # big-endian: check_config_at_start reads it and reports the mismatch.
            self.simulators['ivt_s'].misconfigure(little_endian=True)
            extra['ivt_s.check_config_at_start'] = True
        self.sim_bus = can.Bus(interface='virtual', channel=self.channel)
        self.runner = SimRunner(self.sim_bus, steering + list(self.simulators.values()))
        try:
            self.bridge = BridgeNode(
                context=context, namespace=namespace,
                parameter_overrides=_bridge_parameters(self.channel, banks, commands, extra,
                                                       devices))
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
