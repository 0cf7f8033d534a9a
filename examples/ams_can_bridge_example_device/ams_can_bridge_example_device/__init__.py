# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
``example_bms``: a device type for ams_can_bridge in a package of its own (doc/new_device.md).

The BMS sends one status frame and takes one command: ``protocol`` (the wire format),
``device`` (frames -> BatteryState, the command row), ``sim`` (the simulated BMS), ``probe``
(how probe recognises it) and ``descriptor`` (the entry point naming them all).
"""
