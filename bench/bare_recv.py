# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The reference the bridge must beat: a bare python-can receive loop, nothing else.

    python bench/bare_recv.py INTERFACE CHANNEL SECONDS [key=value ...]

Opens the bus with the same python-can options as the bridge, receives for SECONDS and
prints the number of data frames as JSON. Its CPU is read from outside (/proc).
INTERFACE 'slcan-bulk' opens slcan with the bridge's block reader (can_io/slcan.py)
instead of python-can's: the floor of the bridge's own slcan path.
"""
import json
import sys
import time

import can

sys.path.insert(0, __file__.rsplit('/', 1)[0])
from harness import parse_options  # noqa: E402


def main() -> None:
    """Receive for the given time; print {"frames": n}."""
    interface, channel, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    options = parse_options(sys.argv[4:])
    if interface == 'slcan-bulk':
        from ams_can_bridge.can_io.slcan import open_bulk_slcan
        bus = open_bulk_slcan(channel, **options)
    else:
        bus = can.Bus(interface=interface, channel=channel, **options)
    frames = 0
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end:
            msg = bus.recv(0.1)
            if msg is not None and not msg.is_error_frame:
                frames += 1
    finally:
        bus.shutdown()
    print(json.dumps({'frames': frames}))


if __name__ == '__main__':
    main()
