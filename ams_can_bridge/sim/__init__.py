# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""Device simulators (pure models) and the runner that puts them on a python-can bus."""
