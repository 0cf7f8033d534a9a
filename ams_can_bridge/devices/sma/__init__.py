# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""An SMA-protocol BMS (0x351..): its state, capacity, voltage scale, values and keep-alive."""
