"""The ROS-free engine below ``ros/``: the command gate (and what else the node need not own)."""
