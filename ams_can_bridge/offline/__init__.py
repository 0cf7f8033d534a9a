"""Offline tools without ROS or DDS: CAN logs -> rosbag2 (``log2bag``)."""
