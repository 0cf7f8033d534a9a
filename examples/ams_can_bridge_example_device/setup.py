# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""An example device type for ams_can_bridge, installed as a package of its own."""
from setuptools import setup

setup(
    name='ams_can_bridge_example_device',
    version='0.1.0',
    packages=['ams_can_bridge_example_device'],
    install_requires=['ams_can_bridge'],
    description='ams_can_bridge device type "example_bms": one status frame, one command',
    license='Apache-2.0',
    entry_points={
        # the device type: ams_can_bridge finds it here (its registry.py), nothing else to edit
        'ams_can_bridge.devices': [
            'example_bms = ams_can_bridge_example_device.descriptor:EXAMPLE_BMS',
        ],
    },
)
