# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The dbc device: any BMS from its DBC and a mapping file (doc/own_bms.md), and its profiles."""
