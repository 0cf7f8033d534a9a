# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Device state objects: decoded readings in, BatteryState/diagnostic reports out."""
