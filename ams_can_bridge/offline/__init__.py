# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Offline tools without ROS or DDS: CAN logs -> rosbag2 (``log2bag``)."""
