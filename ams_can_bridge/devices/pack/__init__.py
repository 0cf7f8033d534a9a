# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``pack`` device's ROS-free core: several battery devices' reports in, one battery out.

A pack consumes its members' ``BatteryReport``s (never frames), so the same code runs in the
bridge, in ``log2bag`` and in the demo. ``aggregate`` combines the reports (the table of
doc/packs.md), ``limits`` raises the ``[MOL, RSL, MSL]`` events with debounce and latching,
``derating`` and ``time_to_go`` give the current the pack may take now and for how long;
``core.Pack`` ties them together. The pack sends nothing on the bus: it reports.
"""
