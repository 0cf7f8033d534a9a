# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""ams_can_bridge: battery-management CAN buses to ROS 2."""
