# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The AMS (accumulator management system): its state, banks, master and charger roles."""
