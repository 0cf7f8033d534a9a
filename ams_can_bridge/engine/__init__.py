# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ROS-free core: what to emit and when (core), the command gate (gate).

And the decisions of the node, which only adapts them to ROS: start-up checks (startup),
the live engine's bus view (live) and its timer thread (timer), parameter sets
(param_sets), command service calls (commands).
"""
