"""The ROS-free core of the bridge: what to emit and when (core), the command gate (gate)."""
