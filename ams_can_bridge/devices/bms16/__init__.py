# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The ZEVA BMS16 in its two wire forms: inverter (11-bit, with the SMA frames) and standard."""
