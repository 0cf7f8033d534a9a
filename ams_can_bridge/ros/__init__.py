"""The ROS 2 side: the bridge node, msg conversion, services. Only here is rclpy imported."""
