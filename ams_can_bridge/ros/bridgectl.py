# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``bridgectl`` executable: steer a running bridge without the ``ros2`` command line.

``bridgectl [--node NAME] [--namespace NS] [--timeout S] COMMAND``, COMMAND one of ``arm``,
``disarm``, ``call SERVICE [true|false]``, ``get PARAM``, ``set PARAM VALUE``, ``list``.
What a team on the pip path (no ROS install, so no ``ros2``) needs to arm the bridge, call
a command service and read or set a parameter; it talks to the bridge through rclpy only.

Where things live: the services follow the bridge's *namespace* (``/ams/enable_sc``, or
``/car1/ams/enable_sc``), the parameters are the *node's* (``/ams_can_bridge`` or
``/car1/ams_can_bridge``): ``call ams/enable_sc`` and ``get commands_enabled`` take the names
as the docs write them and ``list`` shows both, with where they are.

Exit codes: 0 done; 1 the bridge answered no (``success: false``, a refused set, an unknown
parameter); 2 no bridge answered within ``--timeout`` (the message names the node and
``ROS_DOMAIN_ID``), or a usage error. Every wait is bounded by ``--timeout``.
"""
from __future__ import annotations

import argparse
import difflib
import os
import re
import sys
import time
from typing import Any, Sequence

import yaml

# The bridge's node name (bridge_node.NODE_NAME, kept equal by a test); monitor loads no rclpy
from ams_can_bridge.ros.monitor import BRIDGE_NODE, check_bridge_name
TIMEOUT = 10.0  # s: discovery on a loaded machine takes seconds; a state command answers
#                 after ams.command_timeout (2 s) at the latest
_SERVICE = re.compile(r'/?[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*')
TRIGGER, SETBOOL = 'std_srvs/srv/Trigger', 'std_srvs/srv/SetBool'
OK, NO, NOT_REACHED = 0, 1, 2


class Usage(Exception):
    """A mistake in what was asked (exit 2): the message says what to change."""


class NoBridge(Exception):
    """No bridge answered in time (exit 2)."""


def parse_args(argv: Sequence[str]) -> argparse.Namespace:
    """Parse bridgectl's arguments; --help and mistakes end here, before ROS starts."""
    parser = argparse.ArgumentParser(
        prog='bridgectl',
        description='Steer a running ams_can_bridge without the ros2 command line: arm or '
        'disarm its commands, call a command service, read or set a parameter, list both. '
        "Services follow the bridge's namespace (/ams/enable_sc); parameters belong to the "
        'node (/ams_can_bridge). Exit 0 done, 1 the bridge said no (success: false, a '
        'refused set), 2 no bridge answered or a usage error.',
        epilog='examples: bridgectl arm; bridgectl call ams/enable_sc; bridgectl call '
        'evms3/set_setup_mode true; bridgectl get commands_enabled; bridgectl set '
        'ams.bank_count 3; bridgectl --namespace car1 list')
    parser.add_argument('--node', default=BRIDGE_NODE, metavar='NAME',
                        help=f"the bridge's node name (default {BRIDGE_NODE}; another one "
                        'when it was started with __node:=NAME)')
    parser.add_argument('--namespace', default='', metavar='NS',
                        help="the bridge's namespace (car1 for a bridge started with "
                        '__ns:=/car1; default: none)')
    parser.add_argument('--timeout', type=float, default=TIMEOUT, metavar='S',
                        help='seconds to wait for the bridge, and then for its answer '
                        f'(default {TIMEOUT:g})')
    commands = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')
    commands.add_parser('arm', help='set commands_enabled true (needs commands_allowed: true '
                        'at launch)')
    commands.add_parser('disarm', help='set commands_enabled false: the bridge stops sending')
    call = commands.add_parser('call', help='call a command service and print its answer')
    call.add_argument('service', metavar='SERVICE',
                      help="relative to the bridge's namespace, e.g. ams/enable_sc")
    call.add_argument('value', nargs='?', choices=('true', 'false'),
                      help='the request of a std_srvs/SetBool service (set_setup_mode, '
                      'set_running)')
    get = commands.add_parser('get', help="print a parameter's value")
    get.add_argument('param', metavar='PARAM')
    put = commands.add_parser('set', help='set a parameter (exit 1 when the bridge refuses)')
    put.add_argument('param', metavar='PARAM')
    put.add_argument('value', metavar='VALUE',
                     help='as in a params file: true, 3, 3.5, static, "[4, 4, 0]"')
    commands.add_parser('list', help="the bridge's services and parameters, with their values")
    args = parser.parse_args(argv)
    if not args.timeout > 0:
        parser.error('--timeout must be > 0 seconds')
    check_bridge_name(parser, args)  # the monitor's check: the same names, the same words
    if args.command == 'call' and not _SERVICE.fullmatch(args.service):
        parser.error(f'SERVICE {args.service!r}: a service name such as ams/enable_sc')
    return args


def parse_value(text: str, current: Any) -> Any:
    """
    Return VALUE as the parameter's type: read as YAML, then made to fit the current value.

    ``3`` for a float parameter is 3.0, a string parameter takes the text as it is; a
    parameter that is not set yet (the configuration values) takes what YAML reads.
    """
    if isinstance(current, str):
        return text
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise Usage(f'VALUE {text!r} is not a value as a params file writes one: {exc}')
    if isinstance(current, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(current, list) and current and isinstance(current[0], float) \
            and isinstance(value, list):
        return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                for v in value]
    if value is None or isinstance(value, dict):
        raise Usage(f'VALUE {text!r}: give a bool, number, string or a list of one of them')
    return value


def show(value: Any) -> str:
    """Return a parameter value as a params file writes it (``(not set)`` when unset)."""
    if value is None:
        return '(not set)'
    text = str(yaml.safe_dump(value, default_flow_style=True, width=10**6))
    return text.strip().removesuffix('\n...').removesuffix(' ...')


class Client:
    """One short-lived rclpy node that talks to one bridge; every wait ends by a deadline."""

    def __init__(self, args: argparse.Namespace, ros_args: list[str]) -> None:
        import rclpy
        self.rclpy = rclpy
        self.timeout = args.timeout
        self.node_name = args.node
        self.namespace = '/' + args.namespace if args.namespace else '/'
        self.fqn = (self.namespace.rstrip('/') + '/' + args.node)
        self.context = rclpy.Context()
        rclpy.init(args=['bridgectl', *ros_args], context=self.context)
        self.node = rclpy.create_node(f'bridgectl_{os.getpid()}', context=self.context,
                                      start_parameter_services=False)

    def close(self) -> None:
        """Destroy the node and end the context."""
        self.node.destroy_node()
        self.context.try_shutdown()

    def no_bridge(self) -> NoBridge:
        """Return the error that names what was looked for, and where."""
        domain = os.environ.get('ROS_DOMAIN_ID', '0 (unset)')
        scope = os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', 'SUBNET (unset)')
        return NoBridge(
            f'no bridge answered: no node {self.fqn} within {self.timeout:g} s on '
            f'ROS_DOMAIN_ID={domain} (ROS_AUTOMATIC_DISCOVERY_RANGE={scope}). Is the bridge '
            'running, in a shell with the same ROS_DOMAIN_ID? Another node name or namespace: '
            '--node / --namespace.')

    def wait_bridge(self, deadline: float) -> None:
        """Wait until the bridge node is in the graph; NoBridge at the deadline."""
        want = (self.node_name, self.namespace)
        while time.monotonic() < deadline:
            if want in self.node.get_node_names_and_namespaces():
                return
            time.sleep(0.1)  # the graph is kept up to date by the middleware: no spin
        raise self.no_bridge()

    def services(self) -> dict[str, str]:
        """Return the bridge's services: full name -> type."""
        found = self.node.get_service_names_and_types_by_node(self.node_name, self.namespace)
        return {name: types[0] for name, types in found if types}

    def request(self, srv_type: Any, name: str, request: Any) -> Any:
        """Call a service of the bridge within the timeout; NoBridge when it never answers."""
        client = self.node.create_client(srv_type, name)
        try:
            if not client.wait_for_service(timeout_sec=self.timeout):
                raise self.no_bridge()
            future = client.call_async(request)
            executor = self.rclpy.executors.SingleThreadedExecutor(context=self.context)
            executor.add_node(self.node)
            try:
                executor.spin_until_future_complete(future, timeout_sec=self.timeout)
            finally:
                executor.remove_node(self.node)
                executor.shutdown(timeout_sec=0)
            if not future.done():
                raise NoBridge(f'{name} of {self.fqn} gave no answer within '
                               f'{self.timeout:g} s (--timeout)')
            return future.result()
        finally:
            self.node.destroy_client(client)

    def service_name(self, service: str) -> str:
        """Return the full name of a service given relative to the bridge's namespace."""
        if service.startswith('/'):
            return service
        return self.namespace.rstrip('/') + '/' + service

    def param_names(self) -> list[str]:
        """Return every parameter name the bridge has, sorted."""
        from rcl_interfaces.srv import ListParameters
        answer = self.request(ListParameters, self.fqn + '/list_parameters',
                              ListParameters.Request())
        return sorted(answer.result.names)

    def get(self, names: list[str]) -> list[Any]:
        """Return the values of these parameters (None: not set, or no such parameter)."""
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python
        answer = self.request(GetParameters, self.fqn + '/get_parameters',
                              GetParameters.Request(names=names))
        if len(answer.values) == len(names):
            return [parameter_value_to_python(v) for v in answer.values]
        if len(names) == 1:  # rclpy answers nothing at all for a value not set yet
            return [None]
        return [self.get([name])[0] for name in names]  # which ones: one by one

    def set(self, name: str, value: Any) -> tuple[bool, str]:
        """Set one parameter; return (successful, the bridge's reason)."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter
        msg = Parameter(name, value=value).to_parameter_msg()
        answer = self.request(SetParameters, self.fqn + '/set_parameters',
                              SetParameters.Request(parameters=[msg]))
        result = answer.results[0]
        return bool(result.successful), str(result.reason)


def _known(client: Client, name: str) -> None:
    """Raise Usage-like refusal (exit 1) when the bridge has no parameter of this name."""
    names = client.param_names()
    if name not in names:
        near = difflib.get_close_matches(name, names, n=1)
        hint = f' Did you mean {near[0]}?' if near else ''
        raise Refused(f'{client.fqn} has no parameter {name!r}.{hint} '
                      '(bridgectl list shows them all)')


class Refused(Exception):
    """The bridge said no (exit 1)."""


def run(args: argparse.Namespace, client: Client) -> int:
    """Carry out one command against the bridge; return the exit code."""
    client.wait_bridge(time.monotonic() + args.timeout)
    if args.command in ('arm', 'disarm'):
        return _set(client, 'commands_enabled', args.command == 'arm')
    if args.command == 'set':
        _known(client, args.param)
        current = client.get([args.param])[0]
        return _set(client, args.param, parse_value(args.value, current))
    if args.command == 'get':
        _known(client, args.param)
        print(show(client.get([args.param])[0]))
        return OK
    if args.command == 'call':
        return _call(args, client)
    return _list(client)


def _set(client: Client, name: str, value: Any) -> int:
    ok, reason = client.set(name, value)
    if not ok:
        raise Refused(f'{client.fqn} refused {name} = {show(value)}: {reason}')
    print(f'{name}: {show(value)}')
    return OK


def _call(args: argparse.Namespace, client: Client) -> int:
    from std_srvs.srv import SetBool, Trigger
    name = client.service_name(args.service)
    types = _service_types(client, name, time.monotonic() + args.timeout)
    kind = types[name]
    if kind == SETBOOL:
        if args.value is None:
            raise Usage(f'{name} is a std_srvs/SetBool service: add true or false')
        answer = client.request(SetBool, name, SetBool.Request(data=args.value == 'true'))
    elif kind == TRIGGER:
        if args.value is not None:
            raise Usage(f'{name} is a std_srvs/Trigger service: it takes no true/false')
        answer = client.request(Trigger, name, Trigger.Request())
    else:
        raise Usage(f'{name} is a {kind} service; bridgectl calls Trigger and SetBool ones')
    print(f'success: {str(answer.success).lower()}')
    print(f'message: {answer.message}')
    return OK if answer.success else NO


def _service_types(client: Client, name: str, deadline: float) -> dict[str, str]:
    """Wait until the bridge offers this service; Usage naming the nearest ones if never."""
    while True:
        found = client.services()
        if name in found or time.monotonic() >= deadline:
            break
        time.sleep(0.1)
    if name not in found:
        ours = [s for s in found if _is_command(client, s)]
        near = difflib.get_close_matches(name, ours, n=3)
        hint = f' Did you mean {", ".join(near)}?' if near else ''
        raise Usage(f'{client.fqn} offers no service {name}.{hint} Services follow the '
                    "bridge's namespace, not its node name (bridgectl list shows them)")
    return found


def _is_command(client: Client, name: str) -> bool:
    """Tell a device's command service from the node's own (parameters, lifecycle)."""
    return not name.startswith(client.fqn + '/')


def _list(client: Client) -> int:
    services = {n: t for n, t in sorted(client.services().items()) if _is_command(client, n)}
    print(f"services of {client.fqn}, under its namespace {client.namespace} (not under the "
          f"node name): bridgectl call NAME")
    for name, kind in services.items():
        relative = name[len(client.namespace.rstrip('/')) + 1:]
        print(f'  {relative:<32} {kind}')
    names = client.param_names()
    values = client.get(names)
    print(f'parameters of the node {client.fqn}: bridgectl get NAME, bridgectl set NAME '
          'VALUE')
    for name, value in zip(names, values):
        print(f'  {name} = {show(value)}')
    return OK


def main(argv: Sequence[str] | None = None) -> int:
    """Run bridgectl; return the exit code (0 done, 1 refused, 2 no bridge or usage)."""
    raw = list(sys.argv[1:] if argv is None else argv)
    ros_args = raw[raw.index('--ros-args'):] if '--ros-args' in raw else []
    own = raw[:len(raw) - len(ros_args)]
    try:
        args = parse_args(own)
    except SystemExit as exc:  # --help (0) or a usage error (2)
        return int(exc.code or 0)
    client = Client(args, ros_args)
    try:
        return run(args, client)
    except Refused as exc:
        print(f'bridgectl: {exc}', file=sys.stderr)
        return NO
    except (Usage, NoBridge) as exc:
        print(f'bridgectl: {exc}', file=sys.stderr)
        return NOT_REACHED
    except KeyboardInterrupt:
        return 130
    finally:
        client.close()


if __name__ == '__main__':
    sys.exit(main())
