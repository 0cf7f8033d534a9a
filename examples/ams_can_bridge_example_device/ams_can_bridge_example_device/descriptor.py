# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The example BMS as ams_can_bridge sees it: one DeviceType, named by the entry point.

Strings only ('module:Name'): reading the descriptor imports none of the code it names.
"""
from ams_can_bridge.devices.descriptor import DeviceType

EXAMPLE_BMS = DeviceType(
    name='example_bms',
    device='ams_can_bridge_example_device.device:ExampleDevice',
    protocol='ams_can_bridge_example_device.protocol',
    simulator='ams_can_bridge_example_device.sim:ExampleSimulator',
    recognisers=('ams_can_bridge_example_device.probe:recognise',),
)
