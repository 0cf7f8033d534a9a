# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
CAN bus I/O: python-can bus lifecycle, replay of recordings, recording of the raw bus.

``CanIo`` opens any python-can interface (or ``replay`` of a log file), receives on its own
thread, reconnects alone after any failure, sends thread-safely and records both directions.
No rclpy here: the ROS node drives this API.
"""
from ams_can_bridge.can_io.config import BusConfig, parse_options
from ams_can_bridge.can_io.core import CanIo
from ams_can_bridge.can_io.replay import ReplayBus

__all__ = ['BusConfig', 'CanIo', 'ReplayBus', 'parse_options']
