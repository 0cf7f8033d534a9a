# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Entry point of the ``bridge`` executable: the bridge node on a multi-threaded executor.

``ros2 run ams_can_bridge bridge --ros-args --params-file config/bms16.yaml``. Exit codes:
0 after Ctrl-C / SIGTERM (clean shutdown: the CAN thread is joined, the bus closed), at the
end of a replay with ``can.replay_exit``, and after ``-h``/``--help`` (usage, ROS is not
started), 2 when the parameters cannot work (the error
names the parameter and what to change) or an argument outside ``--ros-args`` is not known.

The node is a lifecycle node: with ``autostart`` (default true) it configures and activates
itself in its constructor, so a bad parameter still ends the process with exit 2 here; with
``autostart: false`` it waits unconfigured and a lifecycle manager drives it through
``/<node>/change_state`` (a failed configure is answered there, the process keeps running).
"""
from __future__ import annotations

import os
import re
import signal
import sys
import threading
import time
from typing import Any

from ams_can_bridge.registry import DEVICE_TYPES

# rclpy and the node are imported in main(), after the arguments: --help must not load rcl
# (loading it already checks the RMW implementation).

# Waiting command services need threads of their own (telemetry does not use the executor).
EXECUTOR_THREADS = 4
# CPython hands the GIL over every 5 ms by default: a heartbeat thread waking while the
# receive thread parses a burst could wait that long. 1 ms keeps the 50 ms heartbeat's
# jitter small at a negligible cost (measured in bench/run.py, heartbeat scenario).
GIL_SWITCH_INTERVAL = 0.001
STOP_TIMEOUT = 2.0  # s: the longest the executor's callbacks get to finish on a stop
# Another node of this name is looked for while discovery fills the graph, off the start.
NAME_CHECK_PERIOD = 0.5  # s
NAME_CHECK_FOR = 5.0  # s after the start

USAGE = f"""usage: bridge [-h] --ros-args --params-file PARAMS.yaml [-p NAME:=VALUE ...]
       ams-can-bridge [-h] --ros-args ...   (the same program)
       ros2 run ams_can_bridge bridge --ros-args --params-file PARAMS.yaml
       ros2 launch ams_can_bridge bridge.launch.py params_file:=PARAMS.yaml

Bridges battery-management CAN devices (AMS + IVT-S, ZEVA EVMS3 / BMS16, SMA-protocol BMSs,
any BMS from its DBC, a pack of several) to sensor_msgs/BatteryState and /diagnostics.
Parameters come after
--ros-args: a params file (--params-file, sections '/**:' or '<node name>:', then
'ros__parameters:') and single values (-p can.interface:=slcan). The example params files
are installed in
  {{config}}/*.yaml

'bridge' is also iproute2's /usr/sbin/bridge: outside the venv, or after a colcon install
without 'ros2 run', 'bridge' may run that one ('Option "-ros-args" is unknown'). Use
'ams-can-bridge' there: the same program under a name nothing else has.

main parameters:
  can.interface      python-can interface: socketcan (default), slcan, pcan, virtual, replay
  can.channel        can0 (default), /dev/ttyACM0, ... (replay: the log file)
  can.bitrate        bit/s, 0 = leave the adapter as it is
  devices            device instances, e.g. [ams, ivt_s]; each has <name>.type and its IDs
  <name>.type        {', '.join(DEVICE_TYPES)} (default: the instance name)
  commands_allowed   launch-only first key of the transmit gate (default false)
  commands_enabled   second key: nothing is ever sent while false (default false)
  autostart          lifecycle: false waits unconfigured for a manager (default true)

A key the bridge does not know, a bad value or overlapping device IDs stop it (exit 2)
naming what to change. The package's documentation (its doc/ pages; on the ROS index) has
running on a real bus (doc/real_bus.md), every parameter (doc/parameters.md), topic and
service (doc/topics_services.md) and failure mode (doc/failure_modes.md).

options:
  -h, --help         show this help and exit (ROS is not started)
"""


class StopSignals:
    """
    SIGINT / SIGTERM as a request to stop, handled in Python by the main thread.

    Why not rclpy's own handlers: their helper thread triggers the executors' guard
    conditions from C while the main thread, already raising KeyboardInterrupt, destroys
    that executor (a segmentation fault in a thread with no Python frame), and a
    KeyboardInterrupt raised inside the node's constructor leaves the node never destroyed
    and the bus never closed. Here a signal only sets a flag: the node is always built
    whole, then torn down in order (test_bridge_slcan, test_bridge_signals).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        """Install the handlers (main thread only); ``stop`` is set by the first signal."""
        self.stop = threading.Event()
        self.received = 'stop requested'
        for signum in self.SIGNALS:
            signal.signal(signum, self._handle)

    def _handle(self, signum: int, _frame: object) -> None:
        self.request(signal.Signals(signum).name)

    def request(self, reason: str) -> None:
        """Ask for a stop as a signal does (the node's own end: ``can.replay_exit``)."""
        if not self.stop.is_set():
            self.received = reason
        self.stop.set()

    def wait(self) -> None:
        """Block until a signal came (a lock wait is interrupted by signals on POSIX)."""
        while not self.stop.wait(timeout=3600.0):
            pass


def main(args: list[str] | None = None) -> int:
    """Run the bridge until Ctrl-C or SIGTERM; return the process exit code."""
    argv = list(sys.argv if args is None else args)
    own = user_arguments(argv)
    if '-h' in own or '--help' in own:
        print(USAGE.replace('{config}', _config_dir()), end='')
        return 0
    if own:
        print(f'bridge: unknown argument(s) {" ".join(own)}: parameters go after --ros-args '
              '(bridge --ros-args --params-file PARAMS.yaml)\n\n' + USAGE, end='',
              file=sys.stderr)
        return 2
    import rclpy
    from rclpy._rclpy_pybind11 import RCLError
    import rclpy.logging
    from rclpy.signals import SignalHandlerOptions

    from ams_can_bridge.protocols.dbc_mapping.plan import set_params_files
    from ams_can_bridge.ros.bridge_node import BridgeNode, ConfigError, NODE_NAME
    from ams_can_bridge.ros.params import (
        node_name_from_argv, params_file_problems, params_files, unmatched_params_files)
    set_params_files(params_files(argv))  # a dbc device's files beside its params file
    unusable = params_file_paths_problems(params_files(argv))
    if unusable:  # rcl would say "Error opening YAML file", or block on a FIFO
        rclpy.logging.get_logger(NODE_NAME).error('cannot start: ' + '\n'.join(unusable))
        return 2
    sys.setswitchinterval(GIL_SWITCH_INTERVAL)
    signals = StopSignals()
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RCLError as exc:  # a params file that is missing or not YAML: no traceback
        rclpy.logging.get_logger(NODE_NAME).error(f'cannot start: {_rcl_reason(exc)}')
        return 2
    node = None
    try:
        problems = params_file_problems(argv, node_name_from_argv(argv, NODE_NAME))
        if problems:  # before the node exists: nothing armed, the bus not opened
            rclpy.logging.get_logger(NODE_NAME).error('cannot start: ' + '\n'.join(problems))
            return 2
        try:
            node = BridgeNode(argv=argv, on_exit=signals.request)
        except ConfigError as exc:
            rclpy.logging.get_logger(NODE_NAME).error(f'cannot start: {exc}')
            return 2
        for warning in unmatched_params_files(argv, node.get_fully_qualified_name()):
            node.get_logger().warning(warning)
        _watch_for_a_namesake(node)
        if not signals.stop.is_set():
            failed = _spin_until(node, signals)
            if failed:
                return 1
        node.get_logger().info(f'{signals.received}: shutting down')
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


def _spin_until(node: Any, signals: StopSignals) -> str | None:
    """Serve the node's services on an executor thread until a stop; the failure if any."""
    from rclpy.executors import MultiThreadedExecutor

    from ams_can_bridge.ros.spinner import Spinner
    executor = MultiThreadedExecutor(num_threads=EXECUTOR_THREADS)
    executor.add_node(node)
    failure: list[str] = []

    def on_error(exc: BaseException, trace: str) -> None:
        # a service callback that raised: stop, say why, exit 1
        failure.append(f'{type(exc).__name__}: {exc}')
        node.get_logger().fatal(f'the executor stopped: {failure[0]}\n{trace}')

    spinner = Spinner(executor, f'{node.get_name()}-executor', on_error=on_error,
                      on_exit=signals.stop.set)
    try:
        signals.wait()
    finally:
        spinner.stop(timeout=STOP_TIMEOUT)
    return failure[0] if failure else None


def _watch_for_a_namesake(node: Any) -> None:
    """Warn once if another node of this name appears within NAME_CHECK_FOR s of the start."""
    from ams_can_bridge.engine.startup import name_collision
    until = time.monotonic() + NAME_CHECK_FOR

    def check() -> None:
        warning = name_collision(node.get_node_names_and_namespaces(), node.get_name(),
                                 node.get_namespace())
        if warning:
            node.get_logger().warning(warning)
        if warning or time.monotonic() >= until:
            timer.cancel()  # checked enough: the timer stays idle until the node goes

    timer = node.create_timer(NAME_CHECK_PERIOD, check)


def _config_dir() -> str:
    """Return the installed example params files' folder (no ROS needed to find it)."""
    try:
        from ams_can_bridge.protocols.common import msg_defs_dir
        return str(msg_defs_dir().parent / 'config')
    except (ImportError, FileNotFoundError):  # cantools or msg_defs missing: say what it is
        return '<the share folder of ams_can_bridge>/config'


def params_file_paths_problems(paths: list[str]) -> list[str]:
    """Return a line per --params-file that is no readable regular file, with its full path."""
    from ams_can_bridge.input_files import file_problem
    problems = []
    for path in paths:
        problem = file_problem(path)
        if problem:
            full = os.path.abspath(os.path.expanduser(path))
            given = '' if full == path else f' (given as {path})'
            problems.append(f'params file {full}{given} {problem}: give the path of a '
                            'params file (--params-file PARAMS.yaml)')
    return problems


def user_arguments(argv: list[str]) -> list[str]:
    """Return the arguments after the program name that are outside every --ros-args part."""
    own, ros = [], False
    for arg in argv[1:]:
        if arg == '--ros-args':
            ros = True
        elif arg == '--':
            ros = False
        elif not ros:
            own.append(arg)
    return own


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
