"""
Entry point of the ``bridge`` executable: the bridge node on a multi-threaded executor.

``ros2 run ams_can_bridge bridge --ros-args --params-file config/bms16.yaml``. Exit codes:
0 after Ctrl-C / SIGTERM (clean shutdown: the CAN thread is joined, the bus closed),
2 when the parameters cannot work (the error names the parameter and what to change).
"""
from __future__ import annotations

import re
import sys

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
import rclpy.logging

from ams_can_bridge.ros.bridge_node import BridgeNode, ConfigError, NODE_NAME

# Waiting command services need threads of their own (telemetry does not use the executor).
EXECUTOR_THREADS = 4
# CPython hands the GIL over every 5 ms by default: a heartbeat thread waking while the
# receive thread parses a burst could wait that long. 1 ms keeps the 50 ms heartbeat's
# jitter small at a negligible cost (measured in bench/run.py, heartbeat scenario).
GIL_SWITCH_INTERVAL = 0.001
SHUTDOWN_POLL = 1.0  # s: the longest a missed shutdown wake-up can go unnoticed


def main(args: list[str] | None = None) -> int:
    """Run the bridge until Ctrl-C or SIGTERM; return the process exit code."""
    sys.setswitchinterval(GIL_SWITCH_INTERVAL)
    try:
        rclpy.init(args=args)
    except RCLError as exc:  # a params file that is missing or not YAML: no traceback
        rclpy.logging.get_logger(NODE_NAME).error(f'cannot start: {_rcl_reason(exc)}')
        return 2
    node = None
    try:
        try:
            node = BridgeNode()
        except ConfigError as exc:
            rclpy.logging.get_logger(NODE_NAME).error(
                f'cannot start: {exc}')
            return 2
        if not rclpy.ok():
            return 0  # Ctrl-C / SIGTERM came while the node started: nothing to spin
        executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS)
        executor.add_node(node)
        try:
            # Not executor.spin(): with no timers left on the executor (periodic work has a
            # thread of its own) a Ctrl-C whose wake-up the executor misses would leave it
            # waiting forever; one look per SHUTDOWN_POLL bounds that, at ~0.05 % of a core.
            while rclpy.ok():
                executor.spin_once(timeout_sec=SHUTDOWN_POLL)
        finally:
            executor.shutdown(timeout_sec=2.0)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # A signal during start-up shuts the context down under the node or executor being
        # built (RCLError: context is not valid): that is a requested stop, not a crash.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def _rcl_reason(exc: Exception) -> str:
    """Return rcl's reason without its source locations (', at /project/src/...')."""
    text = str(exc).replace('failed to initialize rcl: ', '')
    text = re.sub(r', at [^,]*\.c:\d+', '', text).strip()
    if 'params file' in text:
        text += (' (check that the file exists and is valid YAML: '
                 '<node name or /**>: ros__parameters: ...)')
    return text


if __name__ == '__main__':
    sys.exit(main())
