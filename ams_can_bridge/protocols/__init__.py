# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Pure-Python codecs for every CAN protocol the bridge speaks (no rclpy here).

One module per protocol. Each defines a codec class with:

* ``arbitration_ids``: frozenset of the IDs it decodes;
* ``decode(arbitration_id, data) -> <reading dataclass>``, raising MalformedFrameError;
* ``encode(<message dataclass>) -> Frame``, raising EncodeRangeError.

The errors are in ``ams_can_bridge.errors``, ``Frame`` in ``protocols.common``; what a device
needs of its codec is ``devices.base.Codec``.
"""
