# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The ZEVA EVMS3: its state, its BMS12 modules, its TC chargers, the config read-back."""
