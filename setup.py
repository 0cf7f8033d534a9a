# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ament_python package ams_can_bridge: installs code, DBC files, configs and launch files."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'ams_can_bridge'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/msg_defs', sorted(glob('msg_defs/*.dbc'))),
        ('share/' + PACKAGE + '/config', sorted(glob('config/*.yaml') + glob('config/*.json'))),
        *[('share/' + PACKAGE + '/' + folder, sorted(glob(folder + '/*')))
          for folder in sorted(glob('config/profiles/*'))],  # dbc profiles (DBC, mapping)
        ('share/' + PACKAGE + '/launch', sorted(glob('launch/*.py'))),
        ('share/' + PACKAGE + '/security', ['security/policy.xml']),
    ],
    python_requires='>=3.11',
    install_requires=['setuptools', 'python-can>=4.4', 'cantools>=39', 'pyserial', 'pyyaml',
                      'rosbags>=0.10'],
    zip_safe=False,
    maintainer='ams_can_bridge developers',
    maintainer_email='dev@ams-can-bridge.invalid',
    description=('Battery-management CAN buses (AMS + IVT-S, ZEVA EVMS3/BMS16, SMA, any BMS '
                 'from its DBC, a pack of several) to ROS 2'),
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'bridge = ams_can_bridge.ros.bridge_main:main',
            # the same program under a name iproute2's /usr/sbin/bridge cannot shadow
            'ams-can-bridge = ams_can_bridge.ros.bridge_main:main',
            'simulator = ams_can_bridge.sim.main:main',
            'demo = ams_can_bridge.ros.demo:main',
            'monitor = ams_can_bridge.ros.monitor:main',
            'log2bag = ams_can_bridge.offline.log2bag:main',
            'probe = ams_can_bridge.probe.main:main',
            'bridgectl = ams_can_bridge.ros.bridgectl:main',
        ],
        # Device types (registry.py reads this group; another package adds its own the same
        # way: doc/new_device.md).
        'ams_can_bridge.devices': [
            'ams = ams_can_bridge.devices.builtin:AMS',
            'ivt_s = ams_can_bridge.devices.builtin:IVT_S',
            'evms3 = ams_can_bridge.devices.builtin:EVMS3',
            'bms16 = ams_can_bridge.devices.builtin:BMS16',
            'sma = ams_can_bridge.devices.builtin:SMA',
            'dbc = ams_can_bridge.devices.builtin:DBC',
            'pack = ams_can_bridge.devices.builtin:PACK',
        ],
    },
)
