"""ams_can_bridge: battery-management CAN buses to ROS 2."""
