# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``demo`` executable: the bridge and simulated devices in one process, with a live view.

Simulated AMS (+ IVT-S), EVMS3 (+ BMS12 modules), BMS16 and SMA BMS talk on python-can's
in-process ``virtual`` bus; the real bridge node reads that bus; a small client node in the
same process calls the AMS services (enable_sc -> enable_ts -> enable_drive, hold, abort,
in a loop) and subscribes to the bridge's topics. The terminal view is drawn from those ROS
messages only, so what it shows is exactly what any other ROS subscriber would see.

Exit code 0 after Ctrl-C, SIGTERM or --duration; 2 when the bridge cannot start.
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import threading
import time
from typing import Any

DEVICE_TYPES = {'ams': 'ams', 'ivt_s': 'ivt_s', 'evms3': 'evms3', 'bms16': 'bms16',
                'sma': 'sma'}
STEPS = ('enable_sc', 'enable_ts', 'enable_drive')
DEMO_DOMAINS = range(100, 150)  # ROS_DOMAIN_ID when unset: ./dev's range, not the tests'
DEFAULT_PACK_SCENARIO = 'cell_over@5'
SERVICE_TIMEOUT = 10.0  # s to wait for an AMS answer (the bridge answers by command_timeout)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Parse the demo's own options (ROS arguments after --ros-args are left to rclpy)."""
    parser = argparse.ArgumentParser(
        prog='demo', description='ams_can_bridge demo: bridge + simulated battery devices on '
        'an in-process virtual CAN bus, with a live terminal view. Ctrl-C to stop.')
    parser.add_argument('--duration', type=float, default=0.0,
                        help='stop after this many seconds (default: run until Ctrl-C)')
    parser.add_argument('--plain', action='store_true',
                        help='print plain-text snapshots instead of redrawing in place')
    parser.add_argument('--interval', type=float, default=None,
                        help='seconds between snapshots (default 1.0 plain, 0.25 on a terminal)')
    parser.add_argument('--banks', type=int, default=2, choices=range(1, 6), metavar='1..5',
                        help='number of simulated AMS banks (28 cells each, default 2)')
    parser.add_argument('--hold', type=float, default=None,
                        help='seconds to stay in DRIVE before abort (default 6, shorter with '
                        'a short --duration)')
    parser.add_argument('--fault', action='store_true',
                        help='make the BMS16 fall silent after --fault-after s (shows STALE)')
    parser.add_argument('--fault-after', type=float, default=20.0,
                        help='seconds before the --fault starts (default 20)')
    parser.add_argument('--no-commands', action='store_true',
                        help='do not drive the AMS (bridge stays a listener)')
    parser.add_argument('--namespace', default=None, metavar='NS',
                        help="the demo bridge's namespace (default demo_<process id>: a "
                        'name of its own, so its view and its commands never reach another '
                        'bridge on the same ROS domain; monitor --namespace NS watches it)')
    parser.add_argument('--misconfigured-ivt', action='store_true',
                        help='simulate an IVT-S set up little-endian while the bridge expects '
                        'big-endian: check_config_at_start detects it (ERROR naming '
                        'ivt_s.byte_order; needs commands)')
    parser.add_argument('--pack', action='store_true',
                        help="config/pack.yaml's pack instead: a BMS16 beside an EVMS3 in "
                        'parallel, read as one pack with its limits; implies --no-commands')
    parser.add_argument('--scenario', action='append', default=None, metavar='NAME[@START]',
                        help='with --pack, repeatable: drift, silence or cell_over from START '
                        f's (default: {DEFAULT_PACK_SCENARIO}, a latched MSL event); '
                        "simulator --help tells what each does")
    args = parser.parse_args(argv)
    if args.scenario is not None and not args.pack:
        parser.error('--scenario plays on the pack demo: add --pack')
    if args.pack:
        if args.misconfigured_ivt:
            parser.error('--misconfigured-ivt needs the IVT-S of the default demo: drop --pack')
        from ams_can_bridge.sim.pair import parse_scenario
        try:
            args.scenario = [parse_scenario(text) for text in
                             (args.scenario or [DEFAULT_PACK_SCENARIO])]
        except ValueError as exc:
            parser.error(str(exc))
        args.no_commands = True  # no AMS to drive: the pack sends nothing either
    if args.duration < 0 or (args.interval is not None and args.interval <= 0):
        parser.error('--duration must be >= 0 and --interval > 0')
    args.namespace = (f'demo_{os.getpid()}' if args.namespace is None
                      else args.namespace.strip('/'))
    if args.namespace and not re.fullmatch(r'[A-Za-z_]\w*(/[A-Za-z_]\w*)*', args.namespace):
        parser.error(f'--namespace {args.namespace!r}: a ROS namespace is names of letters, '
                     'digits and _ separated by /, e.g. demo')
    if args.hold is None:
        args.hold = min(6.0, max(1.0, args.duration / 5)) if args.duration else 6.0
    return args


class CommandDriver:
    """
    Walk the AMS through its states with real service calls, in a loop, on its own thread.

    enable_sc -> enable_ts -> enable_drive, hold, abort, rest; a refused step aborts the
    round (abort is always sent) and the loop starts again after the rest.
    """

    def __init__(self, node: Any, device: str, hold: float, rest: float = 2.0,
                 namespace: str = '') -> None:
        from std_srvs.srv import Trigger
        self.node = node
        self.hold = hold
        self.rest = rest
        # Absolute names in the demo bridge's namespace: only the demo's own bridge answers.
        prefix = f'/{namespace}/{device}' if namespace else f'/{device}'
        self.clients = {step: node.create_client(Trigger, f'{prefix}/{step}')
                        for step in STEPS + ('abort',)}
        self.request_type = Trigger.Request
        self.lock = threading.Lock()
        self.last_command = ''
        self.last_answer = ''
        self.stop_event = threading.Event()
        self.thread = threading.Thread(target=self._run, name='demo-commands', daemon=True)

    def start(self) -> None:
        """Start the command loop."""
        self.thread.start()

    def stop(self) -> None:
        """Stop the loop (abort, wait for the answers in flight) and join it."""
        self.stop_event.set()
        if self.thread.is_alive():
            self.thread.join(timeout=2 * SERVICE_TIMEOUT + 1.0)

    def last(self) -> tuple[str, str]:
        """Return (last command, its answer) for the view."""
        with self.lock:
            return self.last_command, self.last_answer

    def _note(self, command: str, answer: str) -> None:
        with self.lock:
            self.last_command, self.last_answer = command, answer

    def call(self, step: str) -> bool:
        """
        Call one Trigger service and wait for its answer; True on success.

        When the demo stops during a wait, abort is sent (it cancels the waiting command
        in the bridge) and the answer is still awaited: no request is left behind in a
        node being destroyed, and the AMS is left in IDLE.
        """
        client = self.clients[step]
        while not client.service_is_ready():
            self._note(step, 'waiting for the service to appear')
            if self.stop_event.wait(0.2):
                return False
        self._note(step, '...')
        started = time.monotonic()
        done = threading.Event()
        future = client.call_async(self.request_type())
        future.add_done_callback(lambda _: done.set())
        aborting = step == 'abort'
        while not done.wait(0.1):
            if self.stop_event.is_set() and not aborting:
                aborting = True
                self.clients['abort'].call_async(self.request_type())
            if time.monotonic() - started > SERVICE_TIMEOUT:
                client.remove_pending_request(future)
                self._note(step, f'no answer within {SERVICE_TIMEOUT:g} s')
                return False
        response = future.result()
        took = time.monotonic() - started
        verdict = 'OK' if response.success else 'REFUSED'
        self._note(step, f'{verdict} in {took:.2f} s: {response.message}')
        return bool(response.success)

    def _run(self) -> None:
        try:
            while not self.stop_event.is_set():
                reached = all(self.call(step) for step in STEPS)
                if self.stop_event.is_set() or (reached and self.stop_event.wait(self.hold)):
                    return
                self.call('abort')
                if self.stop_event.wait(self.rest):
                    return
        finally:
            # Leave the AMS as a driver would: tractive system off.
            if self.clients['abort'].service_is_ready():
                self.call('abort')


def main(argv: list[str] | None = None) -> int:
    """Run the demo; return the process exit code."""
    # Network rule: DDS stays on this machine and on a domain of the demo's own.
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    # (./dev's range: test/conftest.py says which ranges are whose)
    os.environ.setdefault('ROS_DOMAIN_ID', str(DEMO_DOMAINS[os.getpid() % len(DEMO_DOMAINS)]))
    from rclpy.utilities import remove_ros_args

    from ams_can_bridge.ros.watcher import run_with_ros

    raw = sys.argv if argv is None else ['demo'] + list(argv)
    args = parse_args(remove_ros_args(raw)[1:])
    return run_with_ros(raw, lambda stop: _run(args, stop))


def _run(args: argparse.Namespace, stop: threading.Event) -> int:
    """Build everything, show the view until stopped, then tear down in reverse order."""
    from rclpy.executors import MultiThreadedExecutor

    from ams_can_bridge.ros.bridge_node import ConfigError, NODE_NAME
    from ams_can_bridge.ros.demo_rig import DemoRig, DEVICES, PACK_DEVICES
    from ams_can_bridge.ros.demo_view import Screen, show, View
    from ams_can_bridge.ros.spinner import Spinner
    from ams_can_bridge.ros.watcher import BridgeWatcher

    try:
        rig = DemoRig(banks=args.banks, commands=not args.no_commands,
                      misconfigured_ivt=args.misconfigured_ivt, namespace=args.namespace,
                      pack=args.scenario if args.pack else None)
    except ConfigError as exc:
        print(f'demo: the bridge cannot start: {exc}', file=sys.stderr)
        return 2
    # The view watches the demo's own bridge only: its namespace (demo_<pid> by default)
    # keeps it apart from any other bridge on this ROS domain.
    watcher = BridgeWatcher(namespace=args.namespace, bridge_node=NODE_NAME,
                            devices=PACK_DEVICES if args.pack else DEVICES,
                            title=f'ams_can_bridge demo /{args.namespace}',
                            node_name='ams_can_bridge_demo_view')
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(rig.bridge)
    executor.add_node(watcher)
    spinner = Spinner(executor, 'demo-executor')
    driver = None
    if not args.no_commands:
        driver = CommandDriver(watcher, 'ams', args.hold, namespace=args.namespace)
        driver.start()
    faulted = False

    def view(uptime: float) -> View:
        nonlocal faulted
        if args.fault and not faulted and uptime >= args.fault_after:
            rig.silence('bms16')
            faulted = True
        shown = watcher.view(uptime)
        shown.bus = shown.bus or rig.hardware_id
        shown.last_command, shown.last_answer = driver.last() if driver else ('', '')
        if args.misconfigured_ivt:
            shown.notes.append('IVT-S set up little-endian, the bridge expects big-endian: '
                               'see the ivt_s status')
        if args.pack:
            shown.notes.append('pack scenario: ' + ', '.join(
                f'{name} from {start:g} s' for name, start in args.scenario)
                + ' (clear a latched event: pack/clear_events)')
        if args.fault:
            shown.notes.append(f'fault injection: bms16 silent from {args.fault_after:g} s'
                               + (' (now)' if faulted else ''))
        return shown
    try:
        show(Screen(sys.stdout, plain=args.plain), view, stop, args.duration, args.interval)
    finally:
        if driver is not None:
            driver.stop()
            command, answer = driver.last()
            print(f'demo stopped; last command: {command} -> {answer}', flush=True)
        spinner.stop(timeout=3.0)
        watcher.destroy_node()
        rig.close()
    return 0


if __name__ == '__main__':
    sys.exit(main())
