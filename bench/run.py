# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The benchmark suite: every figure of the bridge beside the reference it must beat.

    ./dev bench [--quick] [--soak] [--only NAME,...] [--json bench/results.json]
    ./dev bench --only interleavings --minutes 30 [--seed N]

Each scenario runs the installed code in processes of its own, as on a car (the bridge, a
simulator or probe on the other side of a linked pair of serial ports speaking slcan, a
subscriber), and measures the reference in the same run: a bare python-can receive loop
on the same bus, options and frames, or a bare python-can -> rclpy pipeline. Machines are
noisy: compare the ratios, not the absolute figures across runs. The 10-minute memory soak
runs only with --soak. Results are printed as one table and written as JSON (schema in
bench/README.md). ``interleavings`` (the random-interleaving model of
test/test_engine_interleavings.py, for --minutes, from --seed on) runs only when named.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
from harness import (bridge_args, cpu_share, percentile, process, PYTHON,  # noqa: E402
                     pty_pair, rss_mb, simulator_args, SLCAN_OPEN, write_params)
from ams_can_bridge import realtime  # noqa: E402

PROCS = os.path.join(harness.BENCH, 'procs.py')
SAME_OPTIONS = SLCAN_OPEN + ['timeout=0.5']  # what the bridge uses on slcan by default
REALTIME_PRIORITY = 50  # the heartbeat's extra loaded run, when this user may use SCHED_FIFO
ROWS: list[dict] = []


def row(scenario: str, figure: str, bridge: float, reference: float | None, unit: str,
        target: str = '', met: bool | None = None, note: str = '') -> None:
    """Record one line of the table."""
    ratio = bridge / reference if reference else None
    ROWS.append({'scenario': scenario, 'figure': figure, 'bridge': bridge,
                 'reference': reference, 'ratio': ratio, 'unit': unit, 'target': target,
                 'met': met, 'note': note})
    ref = '' if reference is None else f'{reference:10.2f}'
    rat = '' if ratio is None else f'{ratio:6.2f}x'
    verdict = '' if met is None else ('met' if met else 'NOT met')
    print(f'  {scenario:<24} {figure:<34} {bridge:10.2f} {ref:>10} {rat:>7} {unit:<6} '
          f'{target:<14} {verdict}', flush=True)
    if met is False and note:  # why, under the row: a log cut to its last lines keeps it
        print(f'    {scenario}: {note}', flush=True)


def bare_loop(channel: str, seconds: float, options: list[str]) -> tuple[float, int]:
    """Run the bare python-can loop; return (share of a core, frames received)."""
    proc = subprocess.Popen([PYTHON, os.path.join(harness.BENCH, 'bare_recv.py'), 'slcan',
                             channel, str(seconds + 1.5)] + options, env=harness.env(),
                            stdout=subprocess.PIPE)
    time.sleep(1.0)
    share = cpu_share(proc.pid, seconds)
    out = proc.communicate(timeout=30)[0]
    return share, json.loads(out)['frames']


def cpu_slcan(seconds: float) -> None:
    """Idle and realistic full load over slcan: bridge vs bare python-can, same options.

    The bridge and two bare loops run at the same time, each on its own linked pty pair fed
    by its own simulator (the same frames), so all see the same machine noise; the CPU is
    read over several windows and the medians compared. The issue's reference is
    python-can's own slcan receive loop; the second bare loop reads with the bridge's block
    reader (can_io/slcan.py), the floor of the bridge's own slcan path.
    """
    windows = 3
    with tempfile.TemporaryDirectory() as work, pty_pair() as (a, b), pty_pair() as (c, d), \
            pty_pair() as (e, f):
        params = write_params(os.path.join(work, 'p.yaml'), 'slcan', b, SLCAN_OPEN)
        with process(bridge_args(params), settle=4.0) as bridge:
            # one long window: /proc counts CPU in 10 ms ticks, 0.05 % over 20 s
            idle = cpu_share(bridge.pid, 2 * seconds)
            row('idle (slcan)', '5 devices, silent bus: CPU', idle * 100, None, '%',
                '<= 0.5 %', idle <= 0.005)
            bares = [subprocess.Popen(
                [PYTHON, os.path.join(harness.BENCH, 'bare_recv.py'), interface, port,
                 str(seconds * 2 + 10)] + SAME_OPTIONS, env=harness.env(),
                stdout=subprocess.PIPE) for interface, port in (('slcan', d), ('slcan-bulk', f))]
            with process(simulator_args(a), settle=0.0), process(simulator_args(c)), \
                    process(simulator_args(e), settle=3.0):
                samples = []
                for _ in range(windows):
                    pids = [bridge.pid] + [p.pid for p in bares]
                    c0, t0 = [harness.cpu_seconds(p) for p in pids], time.monotonic()
                    time.sleep(seconds / windows)
                    dt = time.monotonic() - t0
                    samples.append([(harness.cpu_seconds(p) - c) / dt for p, c in zip(pids, c0)])
            frames = [json.loads(p.communicate(timeout=seconds * 2 + 30)[0])['frames']
                      for p in bares]
    rate = 346.0  # the simulators' mix (AMS 5 banks, EVMS3 16 BMS12, BMS16 + SMA)
    loaded = statistics.median(s[0] for s in samples)
    for i, (scenario, what) in enumerate((
            ('full load (slcan)', "python-can's slcan loop"),
            ('full load (slcan floor)', 'a loop with the same block reader'))):
        reference = statistics.median(s[i + 1] for s in samples)
        ratio = statistics.median(s[0] / s[i + 1] for s in samples)
        target, met = ('<= 1.3x', ratio <= 1.3) if i == 0 else ('', None)
        row(scenario, f'CPU, {rate:.0f} frames/s (median of {windows})', loaded * 100,
            reference * 100, '%', target, met,
            f'reference: {what}, same options (timeout=0.5); window ratios '
            + ', '.join(f'{s[0] / s[i + 1]:.2f}' for s in samples)
            + f'; it saw {frames[i]} frames')
        row(scenario, 'CPU per frame', loaded / rate * 1e6, reference / rate * 1e6, 'us')


# bench_pack.py's pack: the EVMS3 and the BMS16 in parallel, every limit configured, so
# derating and the event checks run at each member report
PACK_SECTION = {'type': 'pack', 'members': ['evms3', 'bms16'], 'max_charge_current': 40.0,
                'max_discharge_current': 80.0,
                'limits': {'cell_voltage_max': [4.15, 4.2, 4.25],
                           'cell_voltage_min': [3.0, 2.8, 2.5],
                           'temperature_max': [45.0, 50.0, 55.0],
                           'temperature_min': [5.0, 0.0, -10.0]}}


def cpu_pack(seconds: float, windows: int = 5) -> None:
    """The pack's cost in the whole bridge: two bridges at full load, one with a pack.

    Both run at the same time, each on its own linked pty pair fed by its own simulator
    (the same frames), the one with ``pack`` of ``[evms3, bms16]`` beside the one without,
    so both see the same machine noise. Two rounds with the roles swapped (the bridge
    started first ran ~3 % dearer in an A/A run), ``windows`` CPU windows each; the added
    share is the median of the windows' (with - without) / without (issue 36).
    """
    samples = []  # [without, with] per window
    for first_has_pack in (False, True):
        with tempfile.TemporaryDirectory() as work, pty_pair() as (a, b), \
                pty_pair() as (c, d):
            files = [write_params(os.path.join(work, 'p.yaml'), 'slcan', b, SLCAN_OPEN),
                     write_params(os.path.join(work, 'q.yaml'), 'slcan', d, SLCAN_OPEN,
                                  sections={'pack': PACK_SECTION})]
            if first_has_pack:
                files = [write_params(os.path.join(work, 'p.yaml'), 'slcan', b, SLCAN_OPEN,
                                      sections={'pack': PACK_SECTION}),
                         write_params(os.path.join(work, 'q.yaml'), 'slcan', d, SLCAN_OPEN)]
            with process(bridge_args(files[0])) as one, \
                    process(bridge_args(files[1]), settle=4.0) as two, \
                    process(simulator_args(a)), process(simulator_args(c), settle=3.0):
                pids = [two.pid, one.pid] if first_has_pack else [one.pid, two.pid]
                for _ in range(windows):
                    c0, t0 = [harness.cpu_seconds(p) for p in pids], time.monotonic()
                    time.sleep(seconds / windows / 2)
                    dt = time.monotonic() - t0
                    samples.append([(harness.cpu_seconds(p) - c) / dt
                                    for p, c in zip(pids, c0)])
    shares = [(s[1] - s[0]) / s[0] for s in samples]
    added = statistics.median(shares)
    row('pack (slcan)', f'CPU with a pack of 2 (median of {len(samples)})',
        statistics.median(s[1] for s in samples) * 100,
        statistics.median(s[0] for s in samples) * 100, '%', '<= +10 %', added <= 0.10,
        f'reference: the same bridge without the pack, same frames, same time; added '
        f'{added * 100:.1f} % (windows: ' + ', '.join(f'{x * 100:.1f}' for x in shares) + ' %)')


def virtual_run(mode: str, seconds: float, banks: int = 5, modules: int = 16) -> dict:
    """Run simulators + bridge or bare loop on one in-process virtual bus (procs.virtual)."""
    with tempfile.TemporaryDirectory() as work:
        out = os.path.join(work, 'v.json')
        subprocess.run([PYTHON, PROCS, 'virtual', mode, str(seconds), str(banks),
                        str(modules), out], env=harness.env(), check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=120)
        with open(out, encoding='utf-8') as stream:
            return json.load(stream)


def cpu_virtual(seconds: float) -> None:
    """Realistic full load on the in-process virtual bus, the simulator thread excluded."""
    bridge, bare = virtual_run('bridge', seconds), virtual_run('bare', seconds)
    rate = bridge['frames'] / bridge['seconds']
    row('full load (virtual)', f'CPU, {rate:.0f} frames/s', bridge['cpu'] * 100,
        bare['cpu'] * 100, '%', '<= 1.3x', bridge['cpu'] <= 1.3 * bare['cpu'])
    row('full load (virtual)', 'CPU per frame', bridge['cpu'] / rate * 1e6,
        bare['cpu'] / rate * 1e6, 'us')


def scaling(seconds: float) -> None:
    """CPU and frames/s as the AMS banks and BMS12 modules double (virtual bus)."""
    base = None
    for banks, modules in ((1, 2), (2, 4), (4, 8), (5, 16)):
        result = virtual_run('bridge', seconds, banks, modules)
        rate = result['frames'] / result['seconds']
        per_frame = result['cpu'] / rate * 1e6
        base = base or per_frame
        row('scaling (virtual)', f'{banks} banks, {modules:>2} BMS12: {rate:.0f} frames/s',
            result['cpu'] * 100, None, '%', 'linear', per_frame <= 1.5 * base,
            f'{per_frame:.0f} us/frame')


def latency_run(pipeline: str, seconds: float, rate: float, background: float,
                sent_count: list | None = None) -> list[float]:
    """Latencies (ms) frame written -> ivt_s/battery_state received in another process."""
    with tempfile.TemporaryDirectory() as work, pty_pair() as (a, b):
        if pipeline == 'bridge':
            params = write_params(os.path.join(work, 'p.yaml'), 'slcan', b, SLCAN_OPEN,
                                  devices=('ivt_s',))
            args = bridge_args(params)
        else:
            args = [PYTHON, PROCS, 'reference', b, str(seconds + 12)]
        got, sent = os.path.join(work, 'got.json'), os.path.join(work, 'sent.json')
        with process(args, settle=3.0):
            with process([PYTHON, PROCS, 'subscriber', str(seconds + 5), got], settle=2.5) \
                    as sub:
                subprocess.run([PYTHON, PROCS, 'writer', a, str(seconds), str(rate),
                                str(background), sent], env=harness.env(), check=True,
                               timeout=seconds + 30)
                sub.wait(timeout=seconds + 20)
        with open(got, encoding='utf-8') as s1, open(sent, encoding='utf-8') as s2:
            received, sends = json.load(s1), json.load(s2)
        arrivals = received['arrivals']
        if sent_count is not None:
            sent_count += [len(sends), received['bridge_frames']]
        return [(t - sends[str(tag)]) * 1e3 for tag, t in arrivals if str(tag) in sends]


def latency(seconds: float) -> None:
    """p50/p99/max over slcan, idle and with background frames, beside the reference."""
    for label, background in (('idle', 0.0), ('paced background', 1000.0)):
        ours = latency_run('bridge', seconds, 50.0, background)
        ref = latency_run('reference', seconds, 50.0, background)
        for name, q in (('p50', 0.5), ('p99', 0.99), ('max', 1.0)):
            b, r = percentile(ours, q), percentile(ref, q)
            target = '<= 1.5x' if name == 'p99' else ''
            row(f'latency {label}', f'{name} ({len(ours)} / {len(ref)} samples)', b, r,
                'ms', target, (b <= 1.5 * r) if name == 'p99' else None)


@contextlib.contextmanager
def waiting_calls(service: str):
    """Call a Trigger service over and over from this process (each call waits)."""
    import rclpy
    from std_srvs.srv import Trigger
    rclpy.init()
    node = rclpy.create_node('bench_waiting_caller')
    client = node.create_client(Trigger, service)
    stop = threading.Event()
    calls = [0]

    def loop() -> None:
        while not stop.is_set():
            if client.wait_for_service(timeout_sec=0.5):
                future = client.call_async(Trigger.Request())
                rclpy.spin_until_future_complete(node, future, timeout_sec=10.0)
                calls[0] += 1
    thread = threading.Thread(target=loop, daemon=True)
    thread.start()
    try:
        yield calls
    finally:
        stop.set()
        thread.join(timeout=12)
        node.destroy_node()
        rclpy.shutdown()


def heartbeat_run(seconds: float, load: bool, priority: int = 0) -> list[float]:
    """Heartbeat periods (ms) seen by a reader process on the adapter's side."""
    with tempfile.TemporaryDirectory() as work, pty_pair() as (a, b):
        params = write_params(os.path.join(work, 'p.yaml'), 'slcan', b, SLCAN_OPEN,
                              commands=True, devices=('ams', 'ivt_s', 'evms3', 'bms16', 'sma'),
                              extra={'realtime_priority': priority} if priority else None)
        out = os.path.join(work, 'hb.json')
        # The load comes from a process of its own that only writes to the adapter's side,
        # so the reader's timestamps are not delayed by the load it would otherwise send.
        sender = (process([PYTHON, PROCS, 'load', a, str(seconds + 10)], settle=1.0) if load
                  else contextlib.nullcontext())
        with process(bridge_args(params), settle=4.0), sender:
            calls = contextlib.nullcontext([0]) if not load else waiting_calls('/ams/enable_ts')
            with calls as made:
                subprocess.run([PYTHON, PROCS, 'heartbeat', a, str(seconds), out],
                               env=harness.env(), check=True, timeout=seconds + 30)
        with open(out, encoding='utf-8') as stream:
            stamps = json.load(stream)
    if load and not made[0]:
        print('  (warning: no waiting service call completed during the loaded run)')
    return [(t1 - t0) * 1e3 for t0, t1 in zip(stamps, stamps[1:])]


def heartbeat(seconds: float) -> None:
    """AMS heartbeat period jitter, idle and under full load with a waiting call."""
    runs = [('idle', False, 0), ('load + waiting call', True, 0)]
    if not realtime.use(REALTIME_PRIORITY):  # this user may: show what it gives, same run
        runs.append((f'load + waiting call, realtime_priority {REALTIME_PRIORITY}', True,
                     REALTIME_PRIORITY))
    realtime.use(0)
    for label, load, priority in runs:
        periods = heartbeat_run(seconds, load, priority)
        errors = [abs(p - 50.0) for p in periods]
        missed = sum(1 for p in periods if p > 75.0)
        p99 = percentile(errors, 0.99)
        row(f'heartbeat {label}', f'p99 |period-50ms| ({len(periods)} periods)', p99, None,
            'ms', '<= 2 ms, none missed', p99 <= 2.0 and missed == 0,
            f'mean {statistics.fmean(periods):.2f} ms, missed {missed}, '
            f'max {max(errors):.2f} ms')


def throughput(seconds: float) -> None:
    """Flat out: tagged IVT-S frames as fast as the writer goes; all must arrive published."""
    result = {}
    for pipeline in ('bridge', 'reference'):
        counts: list = []
        got = latency_run(pipeline, seconds, 100000.0, 0.0, counts)
        result[pipeline] = (len(got), *counts)
    (b_got, b_sent, b_taken), (r_got, r_sent, _) = result['bridge'], result['reference']
    row('throughput (slcan)', 'frames/s published, flat out', b_got / seconds,
        r_got / seconds, 'fr/s', 'zero loss', b_got == b_sent == b_taken,
        f'writer sent {b_sent}, the bridge took {b_taken} (its /diagnostics count) and '
        f'published {b_got}; reference: sent {r_sent}, published {r_got}')
    flood = virtual_flood(seconds)
    row('throughput (virtual)', 'device frames/s handled, flat out', flood['bridge_rate'],
        flood['bare_rate'], 'fr/s', 'zero loss', flood['lost'] == 0,
        f"lost {flood['lost']} of {flood['sent']}")


def virtual_flood(seconds: float) -> dict:
    """Flat out on the virtual bus: bridge and bare loop in a process of their own each."""
    with tempfile.TemporaryDirectory() as work:
        out = os.path.join(work, 'f.json')
        subprocess.run([PYTHON, PROCS, 'flood', str(seconds), out], env=harness.env(),
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                       timeout=180)
        with open(out, encoding='utf-8') as stream:
            return json.load(stream)


def soak(minutes: float) -> None:
    """RSS growth of the bridge over a long full-load run (slcan), sampled every 30 s."""
    with tempfile.TemporaryDirectory() as work, pty_pair() as (a, b):
        params = write_params(os.path.join(work, 'p.yaml'), 'slcan', b, SLCAN_OPEN)
        with process(bridge_args(params), settle=4.0) as bridge, \
                process(simulator_args(a), settle=min(60.0, minutes * 15)):  # warm-up
            samples = [rss_mb(bridge.pid)]
            end = time.monotonic() + minutes * 60
            while time.monotonic() < end:
                time.sleep(min(30.0, max(0.0, end - time.monotonic())))
                samples.append(rss_mb(bridge.pid))
    growth = samples[-1] - samples[0]
    half = samples[len(samples) // 2:]
    row('memory soak (slcan)', f'RSS growth over {minutes:g} min', growth, None, 'MB',
        '<= 5 MB', growth <= 5.0,
        f'{samples[0]:.1f} -> {samples[-1]:.1f} MB (min {min(samples):.1f}, max '
        f'{max(samples):.1f}; second half {half[-1] - half[0]:+.2f} MB)')


def log2bag(seconds: float) -> None:
    """The log2bag conversion rate beside python-can's read of the same log (issue 39)."""
    import bench_log2bag
    from bench_log2bag import RATIO_TARGET
    for result in bench_log2bag.measure(seconds, ('log', 'blf')):
        row('log2bag', f'.{result["format"]} frames/s', result['log2bag_fps'],
            result['python_can_read_fps'], 'fr/s', '>= 0.5x',
            result['log2bag_fps'] >= RATIO_TARGET * result['python_can_read_fps'])


def probe(seconds: float) -> None:
    """probe reading and recognising a log beside log2bag on the same log, in one run."""
    import bench_probe
    for result in bench_probe.measure(seconds, ('log', 'blf')):
        row('probe', f'.{result["format"]} frames/s', result['probe_fps'],
            result['log2bag_fps'], 'fr/s', '>= log2bag', result['met'],
            f'reference: log2bag on the same log; python-can alone reads '
            f'{result["python_can_read_fps"]:,.0f} frames/s')


def dbc_device(seconds: float) -> None:
    """A dbc device (our AMS over its DBC) beside the built-in AMS device, same frames."""
    import bench_dbc
    figures = bench_dbc.run(5, seconds, 7)
    row('dbc device', 'us/frame vs built-in ams (median)', figures['median_us']['dbc'],
        figures['median_us']['ams'], 'us', f'<= {bench_dbc.TARGET}x', figures['met'],
        f"{figures['frames']} AMS frames (5 banks); handle_frame + battery_report per "
        f"primary; decode alone {figures['median_us']['compiled']:.2f} us compiled vs "
        f"{figures['median_us']['cantools']:.2f} us cantools")


def interleavings(minutes: float, seed: int, priority: int = 0) -> None:
    """The interleaving model for minutes: sequences run, invariants broken (their seeds)."""
    import bench_interleavings
    problem = realtime.use(priority)  # the model's senders, as the node's realtime_priority
    if problem:
        raise SystemExit(problem)
    figures = bench_interleavings.run(minutes, seed)
    broken = figures['broken_seeds']
    row('interleavings', f"sequences in {figures['minutes']:g} min", figures['sequences'],
        None, 'seq', 'none broken', not broken,
        f"up to {figures['steps_each']} steps each, seeds {seed}.."
        f"{seed + figures['seeds'] - 1}; broken: {broken or 'none'}; "
        f"{len(figures['excused_gaps_ms'])} gaps the machine's (its delay of a separate "
        "process as long); senders at "
        + (f'SCHED_FIFO {priority}' if priority else 'the default scheduling'))


SCENARIOS = {
    'cpu_slcan': lambda q: cpu_slcan(5.0 if q else 10.0),
    'cpu_virtual': lambda q: cpu_virtual(5.0 if q else 10.0),
    'cpu_pack': lambda q: cpu_pack(20.0 if q else 60.0),
    'scaling': lambda q: scaling(4.0 if q else 6.0),
    'latency': lambda q: latency(8.0 if q else 20.0),
    'heartbeat': lambda q: heartbeat(8.0 if q else 20.0),
    'throughput': lambda q: throughput(3.0 if q else 5.0),
    'log2bag': lambda q: log2bag(60.0 if q else 120.0),
    'dbc': lambda q: dbc_device(30.0 if q else 60.0),
    'probe': lambda q: probe(30.0 if q else 60.0),
}


def main() -> None:
    """Run the scenarios; print the table; write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--quick', action='store_true', help='shorter runs (noisier)')
    parser.add_argument('--soak', action='store_true', help='also the 10-minute memory soak')
    parser.add_argument('--soak-minutes', type=float, default=10.0)
    parser.add_argument('--only', default='', help='comma-separated scenarios: '
                        + ', '.join(SCENARIOS) + ', soak, interleavings')
    parser.add_argument('--minutes', type=float, default=1.0,
                        help='interleavings: how long to run new sequences')
    parser.add_argument('--seed', type=int, default=1,
                        help='interleavings: the first sequence\'s seed')
    parser.add_argument('--realtime-priority', type=int, default=0,
                        help="interleavings: the model's senders at this SCHED_FIFO priority "
                             '(the node parameter realtime_priority; 0 = off)')
    parser.add_argument('--json', default=os.path.join(harness.BENCH, 'results.json'))
    parser.add_argument('--update-readme', metavar='FILE', nargs='?', default='',
                        const=os.path.join(harness.BENCH, 'README.md'),
                        help='only rewrite the table between the bench-table markers of FILE '
                        '(default bench/README.md, where the figures live) from the JSON (no '
                        'run)')
    args = parser.parse_args()
    if args.update_readme:
        with open(args.json, encoding='utf-8') as stream:
            update_readme(args.update_readme, json.load(stream))
        return
    names = [n for n in args.only.split(',') if n] or list(SCENARIOS)
    started = time.monotonic()
    print(f'  {"scenario":<24} {"figure":<34} {"bridge":>10} {"reference":>10} {"ratio":>7} '
          f'{"unit":<6} {"target":<14} verdict')
    for name in names:
        if name == 'soak':  # --only soak: the soak alone
            args.soak = True
            continue
        if name == 'interleavings':  # only when named: it runs for --minutes
            interleavings(args.minutes, args.seed, args.realtime_priority)
            continue
        SCENARIOS[name](args.quick)
    if args.soak:
        soak(args.soak_minutes)
    result = {
        'machine': {'node': platform.node(), 'cpus': os.cpu_count(),
                    'cpu': _cpu_model(), 'python': platform.python_version(),
                    'kernel': platform.release()},
        'date': time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime()),
        'duration_s': round(time.monotonic() - started, 1),
        'quick': args.quick,
        'rows': ROWS,
    }
    with open(args.json, 'w', encoding='utf-8') as stream:
        json.dump(result, stream, indent=2)
    print(f'wrote {args.json} ({result["duration_s"]} s)')


def markdown(result: dict) -> str:
    """Return the results as bench/README.md's Markdown table (with the machine line)."""
    m = result['machine']
    lines = [f"Taken {result['date']} on {m['cpus']} cores of {m['cpu']} (Python "
             f"{m['python']}, Linux {m['kernel']}), a shared machine"
             + (' (--quick)' if result['quick'] else '') + '.', '',
             '| scenario | figure | bridge | reference | ratio | target | |',
             '|---|---|---|---|---|---|---|']
    for r in result['rows']:
        ref = '' if r['reference'] is None else f"{r['reference']:,.2f}"
        ratio = '' if r['ratio'] is None else f"{r['ratio']:.2f}x"
        met = '' if r['met'] is None else ('met' if r['met'] else '**not met**')
        cells = [r['scenario'], r['figure'], f"{r['bridge']:,.2f} {r['unit']}", ref, ratio,
                 r['target'], met]
        lines.append('| ' + ' | '.join(c.replace('|', '\\|') for c in cells) + ' |')
    return '\n'.join(lines)


def update_readme(path: str, result: dict) -> None:
    """Replace the table between the bench-table markers of a Markdown file (bench/README.md)."""
    with open(path, encoding='utf-8') as stream:
        text = stream.read()
    start, end = '<!-- bench-table -->', '<!-- /bench-table -->'
    head, found, rest = text.partition(start)
    _, closed, tail = rest.partition(end)
    if not (found and closed):
        sys.exit(f'bench/run.py: {path} has no {start} ... {end} markers to write the table '
                 'between')
    with open(path, 'w', encoding='utf-8') as stream:
        stream.write(f'{head}{start}\n{markdown(result)}\n{end}{tail}')


def _cpu_model() -> str:
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as stream:
            for line in stream:
                if line.startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


if __name__ == '__main__':
    main()
