# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The IVT-S current sensor: its state, its command exchanges (0x411/0x511) and their sequences."""
