# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``monitor`` executable: the demo's live table, attached to any running bridge.

``monitor [--namespace car1] [--node ams_can_bridge] [--plain]`` subscribes to one bridge's
``<device>/battery_state`` topics and ``/diagnostics`` and draws the table the demo draws
(``demo_view``), redrawn 4 times a second on a terminal, a snapshot a second otherwise:
what a team without a desktop looks at on the car's computer over SSH. Its devices are found
from the ROS graph (the BatteryState topics the bridge node publishes) and from the
diagnostics names ``<namespace>/<node>: <device>``: whatever devices the bridge has,
``dbc`` devices included. The bridge marks a silent device STALE; a device (or the CAN bus)
that nothing at all was heard from for ``--stale-after`` seconds (a bridge that stopped) is
marked STALE here, its numbers no longer shown.

It only subscribes: it creates no service client, so it commands nothing. It is an ordinary
ROS node of the shell it runs in (ROS_DOMAIN_ID and discovery range as for any ROS tool).
Exit code 0 after Ctrl-C, SIGTERM or --duration; 2 for bad arguments.
"""
from __future__ import annotations

import argparse
import re
import sys
import threading
from typing import Sequence

# The bridge's node name (bridge_node.NODE_NAME): importing that module here would load
# rclpy for `monitor --help`; a test keeps the two equal.
BRIDGE_NODE = 'ams_can_bridge'
STALE_AFTER = 3.0  # s: a bridge publishes each device at least every second, even when silent
_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')


def _own_args(argv: Sequence[str]) -> list[str]:
    """Return the monitor's own arguments: those before --ros-args (rclpy takes the rest)."""
    argv = list(argv)
    return argv[:argv.index('--ros-args')] if '--ros-args' in argv else argv


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """Parse the monitor's options; a mistake exits 2 with one line naming it (no ROS)."""
    parser = argparse.ArgumentParser(
        prog='monitor', description="ams_can_bridge monitor: the demo's live table of a "
        "running bridge's devices, from its battery_state topics and /diagnostics. Only "
        'subscribes (never calls a service). Ctrl-C to stop.')
    parser.add_argument('--namespace', default='', metavar='NS',
                        help="the bridge's namespace (car1 for a bridge started with "
                        '__ns:=/car1; default: none)')
    parser.add_argument('--node', default=BRIDGE_NODE, metavar='NAME',
                        help=f"the bridge's node name (default {BRIDGE_NODE}; another one "
                        'when it was started with __node:=NAME)')
    parser.add_argument('--plain', action='store_true',
                        help='print plain-text snapshots instead of redrawing in place')
    parser.add_argument('--interval', type=float, default=None, metavar='S',
                        help='seconds between draws (default 0.25 on a terminal, 1.0 plain)')
    parser.add_argument('--duration', type=float, default=0.0, metavar='S',
                        help='stop after S seconds (default: run until Ctrl-C)')
    parser.add_argument('--stale-after', type=float, default=STALE_AFTER, metavar='S',
                        help='mark a device STALE when nothing about it came for S seconds '
                        f'(default {STALE_AFTER:g}; longer when the bridge publishes '
                        '/diagnostics less often)')
    args = parser.parse_args(argv)
    if args.duration < 0 or (args.interval is not None and args.interval <= 0):
        parser.error('--duration must be >= 0 and --interval > 0')
    if args.stale_after <= 0:
        parser.error('--stale-after must be > 0')
    check_bridge_name(parser, args)
    return args


def check_bridge_name(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Check --namespace and --node (the namespace without its slashes); exit 2 naming it."""
    args.namespace = args.namespace.strip('/')
    if args.namespace and not all(_NAME.fullmatch(t) for t in args.namespace.split('/')):
        parser.error(f'--namespace {args.namespace!r}: a ROS namespace is names of letters, '
                     'digits and _ separated by /, e.g. car1')
    if not _NAME.fullmatch(args.node):
        parser.error(f'--node {args.node!r}: a ROS node name is letters, digits and _, '
                     f'e.g. {BRIDGE_NODE}')


def main(argv: Sequence[str] | None = None) -> int:
    """Run the monitor; return the process exit code."""
    raw = sys.argv[1:] if argv is None else list(argv)
    args = parse_args(_own_args(raw))  # --help and mistakes end here, before ROS starts
    from ams_can_bridge.ros.watcher import run_with_ros
    return run_with_ros(['monitor', *raw], lambda stop: _run(args, stop))


def _run(args: argparse.Namespace, stop: threading.Event) -> int:
    """Watch the bridge and draw until stopped."""
    from rclpy.executors import SingleThreadedExecutor

    from ams_can_bridge.ros.demo_view import Screen, show
    from ams_can_bridge.ros.spinner import Spinner
    from ams_can_bridge.ros.watcher import BridgeWatcher

    watcher = BridgeWatcher(args.namespace, args.node, stale_after=args.stale_after)
    executor = SingleThreadedExecutor()
    executor.add_node(watcher)
    spinner = Spinner(executor, 'monitor-executor')
    try:
        show(Screen(sys.stdout, plain=args.plain), watcher.view, stop, args.duration,
             args.interval)
    finally:
        spinner.stop(timeout=3.0)
        watcher.destroy_node()
    return 0


if __name__ == '__main__':
    sys.exit(main())
