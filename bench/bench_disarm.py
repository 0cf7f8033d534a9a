# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Measure a disarm sent while a 3,000,000-value parameter set is in flight (issue 26, point 3).

The installed bridge (an AMS armed, its heartbeat every 50 ms, and an EVMS3) runs on one side
of a linked pty pair (slcan); a recorder process on the other side stamps every heartbeat
(python-can's slcan receive time, the wall clock). A client node sends
``evms3.config.cells_per_module`` with 3,000,000 values through ``set_parameters``, and right
behind it ``commands_enabled: false``. Printed per round: the disarm's answer time (from its
request to its answer), the time of the last heartbeat relative to the disarm's request
(negative: before it was even sent) and to its answer, and the big set's own answer time
and reason. The reference, "what rclpy needs to receive such a request": a plain rclpy node
with one integer-array parameter, answering the same set after a length check alone.

    .venv/bin/python bench/bench_disarm.py [--rounds 3] [--size 3000000] [--before DIR]

``--before DIR``: run the bridge from another source tree (``git archive main | tar -x -C
DIR``), to measure the code before a change with the same client and recorder.
"""
from __future__ import annotations

import argparse
import array
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402  (network rule before rclpy is imported)

CELLS = 'evms3.config.cells_per_module'
REFERENCE_NODE = 'bench_disarm_reference'
MAX_LENGTH = 16  # the reference refuses past this length, as the bridge does


def reference_node() -> None:
    """Role: a plain rclpy node with one integer-array parameter, a length check only."""
    import rclpy
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.parameter import Parameter
    rclpy.init()
    node = rclpy.create_node(REFERENCE_NODE)
    node.declare_parameter('cells', Parameter.Type.INTEGER_ARRAY)

    def check(params: list) -> SetParametersResult:
        for param in params:
            if param.value is not None and len(param.value) > MAX_LENGTH:
                return SetParametersResult(successful=False, reason='too long')
        return SetParametersResult(successful=True)
    node.add_on_set_parameters_callback(check)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, Exception):
        pass


class Client:
    """A client node that times parameter sets to a node's set_parameters service."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        rclpy.init()
        self.node = rclpy.create_node('bench_disarm_client')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()
        self.clients: dict[str, object] = {}

    def client(self, node_name: str):
        from rcl_interfaces.srv import SetParameters
        if node_name not in self.clients:
            client = self.node.create_client(SetParameters, f'/{node_name}/set_parameters')
            if not client.wait_for_service(timeout_sec=30.0):
                raise RuntimeError(f'/{node_name}/set_parameters is not offered')
            self.clients[node_name] = client
        return self.clients[node_name]

    def send(self, node_name: str, name: str, value) -> dict:
        """Send one set; return {'sent': t, 'future': f, 'answered': [t]} (wall clock)."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter
        request = SetParameters.Request(parameters=[Parameter(name, value=value)
                                                    .to_parameter_msg()])
        out: dict = {'answered': []}
        out['sent'] = time.time()
        out['future'] = self.client(node_name).call_async(request)
        out['future'].add_done_callback(lambda _: out['answered'].append(time.time()))
        return out

    @staticmethod
    def wait(call: dict, timeout: float = 300.0) -> tuple[float, object]:
        """Wait for a call's answer; return (answer time s, its first result)."""
        deadline = time.monotonic() + timeout
        while not call['answered'] and time.monotonic() < deadline:
            time.sleep(0.001)
        if not call['answered']:
            raise RuntimeError(f'no answer within {timeout} s')
        return call['answered'][0] - call['sent'], call['future'].result().results[0]

    def close(self) -> None:
        import rclpy
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown()


def measure(args: argparse.Namespace) -> dict:
    """Run the rounds against the bridge and the reference; return the figures."""
    huge = array.array('q', [12]) * args.size
    results: dict = {'size': args.size, 'rounds': [], 'reference_s': [], 'disarm_alone_s': []}
    with tempfile.TemporaryDirectory(prefix='bench_disarm_') as work, \
            harness.pty_pair() as (bridge_side, adapter_side):
        params = harness.write_params(os.path.join(work, 'params.yaml'), 'slcan', bridge_side,
                                      harness.SLCAN_OPEN, commands=True,
                                      devices=('ams', 'evms3'))
        stamps_file = os.path.join(work, 'heartbeats.json')
        env = harness.env()
        if args.before:
            env['PYTHONPATH'] = args.before
        # procs.py heartbeat: stamps every heartbeat until SIGTERM (the hour is a bound only)
        recorder = subprocess.Popen([harness.PYTHON, os.path.join(harness.BENCH, 'procs.py'),
                                     'heartbeat', adapter_side, '3600', stamps_file],
                                    env=harness.env())
        # python -m puts its working directory first on sys.path: run it in the tree measured
        bridge = subprocess.Popen(harness.bridge_args(params), env=env, cwd=args.before,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        reference = subprocess.Popen([harness.PYTHON, __file__, '--role', 'reference'],
                                     env=harness.env(), stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        client = Client()
        try:
            for _ in range(args.rounds):
                arm_sent = time.time()
                answer, result = client.wait(client.send('ams_can_bridge', 'commands_enabled',
                                                         True))
                assert result.successful, result.reason
                time.sleep(1.0)  # heartbeats flowing
                big = client.send('ams_can_bridge', CELLS, huge)
                disarm = client.send('ams_can_bridge', 'commands_enabled', False)
                disarm_s, disarm_result = client.wait(disarm)
                big_s, big_result = client.wait(big)
                results['rounds'].append({
                    'arm_sent': arm_sent, 'disarm_sent': disarm['sent'],
                    'disarm_answer_s': disarm_s,
                    'disarm_ok': disarm_result.successful,
                    'big_sent': big['sent'], 'big_answer_s': big_s,
                    'big_reason': big_result.reason[:300],  # before the fix: 12 MB of repr
                    'serialize_s': disarm['sent'] - big['sent']})
                time.sleep(0.5)
            for row, later in zip(results['rounds'], results['rounds'][1:]):
                row['rearm_sent'] = later['arm_sent']
            results['rounds'][-1]['rearm_sent'] = time.time()
            for _ in range(args.rounds):
                client.wait(client.send('ams_can_bridge', 'commands_enabled', True))
                results['disarm_alone_s'].append(client.wait(client.send(
                    'ams_can_bridge', 'commands_enabled', False))[0])
                results['reference_s'].append(client.wait(client.send(
                    REFERENCE_NODE, 'cells', huge))[0])
        finally:
            client.close()
            for proc in (reference, bridge):
                proc.send_signal(signal.SIGINT)
            recorder.terminate()
            for proc in (reference, bridge, recorder):
                try:
                    proc.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        with open(stamps_file, encoding='utf-8') as stream:
            stamps = json.load(stream)
    ends = [row['rearm_sent'] for row in results['rounds']]
    for row, end in zip(results['rounds'], ends):
        # the round's heartbeats: from before the big set until the next arming
        mine = [t for t in stamps if row['arm_sent'] < t < end]
        answered = row['disarm_sent'] + row['disarm_answer_s']
        row['last_heartbeat_s'] = (max(mine) - row['disarm_sent']) if mine else None
        row['heartbeats_after_answer'] = len([t for t in mine if t > answered])
    return results


def report(results: dict) -> None:
    """Print one line per round and the medians."""
    print(f'set of {results["size"]:,} values in flight, then commands_enabled: false')
    print('round  disarm answer s  last heartbeat s (vs disarm sent)  heartbeats stamped after '
          'the answer  big set answer s  client serialize s')
    for k, row in enumerate(results['rounds'], 1):
        print(f'{k:5}  {row["disarm_answer_s"]:15.3f}  {row["last_heartbeat_s"]:33.3f}  '
              f'{row["heartbeats_after_answer"]:35}  {row["big_answer_s"]:16.3f}  '
              f'{row["serialize_s"]:18.3f}')
    print(f'big set answer: {results["rounds"][0]["big_reason"]!r}')
    med = statistics.median
    print(f'median disarm answer {med(r["disarm_answer_s"] for r in results["rounds"]):.3f} s;'
          f' disarm alone {med(results["disarm_alone_s"]):.3f} s; reference (plain rclpy '
          f'node, same set, length check only) {med(results["reference_s"]):.3f} s')


def main() -> int:
    """Parse the arguments, run a role or the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--size', type=int, default=3_000_000)
    parser.add_argument('--before', help='source tree to run the bridge from (PYTHONPATH)')
    parser.add_argument('--json', help='also write the figures to this file')
    parser.add_argument('--role', choices=('reference',), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == 'reference':
        reference_node()
        return 0
    results = measure(args)
    report(results)
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump(results, stream, indent=1)
    return 0


if __name__ == '__main__':
    sys.exit(main())
