# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""A DBC plus a mapping file read into a plan: which signals make which BatteryState field."""
