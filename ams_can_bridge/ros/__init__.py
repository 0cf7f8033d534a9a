# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The ROS 2 side: the bridge node, msg conversion, services. Only here is rclpy imported."""
