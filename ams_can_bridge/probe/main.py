# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The ``probe`` executable: which devices are on this bus, and a params file that reads them.

    probe LOG [--output PARAMS.yaml] [--json] [--dbc FILE --mapping FILE]...
    probe --interface slcan --channel /dev/ttyACM0 [--bitrate 500000|auto] [--duration 10]

It never sends a frame. Every user mistake (a log that cannot be read, an interface that
does not open, a bus without a frame, a DBC that does not load) is one line and exit 2.
"""
from __future__ import annotations

import argparse
from dataclasses import asdict
import os
import sys
from typing import Sequence

from ams_can_bridge.can_io import parse_options
from ams_can_bridge.errors import ConfigError, LogFileError
from ams_can_bridge.probe import output, report
from ams_can_bridge.probe.dbc import DbcRecogniser
from ams_can_bridge.probe.evidence import Setting
from ams_can_bridge.probe.recognise import INSTALLED, recognise
from ams_can_bridge.probe.sources import listen_live, LiveInfo, read_log, AUTO_RATES

DEFAULT_DURATION_S = 10.0


def _bitrate(text: str) -> int | str:
    if text == 'auto':
        return text
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value <= 0:
        raise argparse.ArgumentTypeError(f'{text!r}: a rate in bit/s (e.g. 500000) or auto')
    return value


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0 < value <= 86400:
        raise argparse.ArgumentTypeError(f'{text!r}: seconds, more than 0')
    return value


def build_parser() -> argparse.ArgumentParser:
    """Return the command line of ``probe``."""
    p = argparse.ArgumentParser(
        prog='probe', description='Find the battery devices on a CAN bus (a log, or a live '
        'bus it only listens to: it never sends), report the evidence and every ID it cannot '
        'place, and write a params file that bridge and log2bag accept as it is.')
    p.add_argument('log', nargs='?', help='CAN log as log2bag reads it (.log .asc .blf .trc '
                   '.csv); or listen live with --interface/--channel')
    p.add_argument('--interface', help='python-can interface to listen on (slcan, socketcan, '
                   'pcan, ...)')
    p.add_argument('--channel', help='its channel (/dev/ttyACM0, can0, ...)')
    p.add_argument('--bitrate', type=_bitrate, default=0, metavar='BITS|auto',
                   help='bit/s; auto tries ' + ', '.join(str(r) for r in AUTO_RATES)
                   + ' listen-only (slcan); default: leave the adapter as it is')
    p.add_argument('--duration', type=_seconds, default=DEFAULT_DURATION_S, metavar='S',
                   help=f'seconds to listen live (default {DEFAULT_DURATION_S:g})')
    p.add_argument('--option', action='append', default=[], metavar='KEY=VALUE',
                   help='python-can interface option, repeatable (e.g. sleep_after_open=0)')
    p.add_argument('--output', metavar='PARAMS.yaml',
                   help='write the params file of the devices found (checked with the '
                   "bridge's start-up checks; commands_allowed: false); never the log "
                   'it reads; an existing file only with --force')
    p.add_argument('--force', action='store_true',
                   help='replace an existing --output file')
    p.add_argument('--json', action='store_true', help='print the report as JSON')
    p.add_argument('--dbc', action='append', default=[], metavar='FILE',
                   help='a BMS DBC to look for (with --mapping, repeatable in pairs)')
    p.add_argument('--mapping', action='append', default=[], metavar='FILE',
                   help="that DBC's mapping file (doc/own_bms.md)")
    return p


def _check(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    live = args.interface is not None or args.channel is not None
    if args.log is not None and live:
        parser.error('give a LOG or --interface/--channel, not both')
    if args.log is None and not live:
        parser.error('give a LOG to read, or --interface and --channel to listen to')
    if live and (args.interface is None or args.channel is None):
        parser.error('listening live needs both --interface and --channel')
    if len(args.dbc) != len(args.mapping):
        parser.error(f'{len(args.dbc)} --dbc and {len(args.mapping)} --mapping: give them in '
                     'pairs')


def _bus_lines(live: LiveInfo | None) -> list[Setting]:
    """Return the can.* settings: where probe listened, or what to check for a log."""
    if live is None:
        return [Setting('interface', 'socketcan', 'check: a log does not say which adapter '
                        'took it, nor at which rate: set yours (doc/real_bus.md)', False),
                Setting('channel', 'can0', '', False), Setting('bitrate', 500000, '', False)]
    tried = ', '.join(f'{rate}: {frames} frames' for rate, frames in live.tried)
    how = (f'found by listening at the standard rates (listen-only): {tried}' if live.tried
           else 'where probe listened')
    if not live.rate_determined:
        return [Setting('interface', live.interface, 'where probe listened'),
                Setting('channel', live.channel, 'where probe listened'),
                Setting('bitrate', live.bitrate, 'check: frames came at more than one rate '
                        f'({tried}): the link has no bit rate of its own (a pty or a '
                        "software link?), so the rate was not determined: set your bus's",
                        False)]
    return [Setting('interface', live.interface, 'where probe listened'),
            Setting('channel', live.channel, 'where probe listened'),
            Setting('bitrate', live.bitrate, how)]


def main(argv: Sequence[str] | None = None) -> int:
    """Run probe; 0 when it reported, 2 on unusable input (one line saying what)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    _check(parser, args)
    live: LiveInfo | None = None
    try:
        if args.output:
            output.check_target(args.output, [p for p in [args.log, *args.dbc, *args.mapping]
                                              if p is not None], args.force)
        recognisers = [*INSTALLED]
        if args.dbc:
            recognisers.append(DbcRecogniser(list(zip(args.dbc, args.mapping))))
        if args.log is not None:
            source = args.log
            traffic = read_log(args.log)
        else:
            options = parse_options(args.option)
            source = f'{args.interface}:{args.channel}'
            traffic, live = listen_live(args.interface, args.channel, args.bitrate,
                                        args.duration, options, sys.stderr)
            source = live.describe()
        findings = recognise(traffic, recognisers)
        if args.json:
            print(report.as_json(findings, traffic, source, asdict(live) if live else None))
        else:
            print(report.text(findings, traffic, source))
        if args.output:
            output.write(args.output, output.render(findings, _bus_lines(live), source))
            if not args.json:
                print(f'wrote {args.output}: {len(findings.written)} device(s), '
                      'commands_allowed: false')
    except (ConfigError, LogFileError, ValueError) as exc:
        print(f'probe: {exc}', file=sys.stderr)
        return 2
    except OSError as exc:  # e.g. the folder of --output is not writable
        print(f'probe: {exc.filename or ""}: {exc.strerror or exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('probe: interrupted', file=sys.stderr)
        return 130
    except BrokenPipeError:  # probe LOG | head: the reader has all it wanted
        sys.stdout = open(os.devnull, 'w')  # no second error when Python flushes at exit
        return 0
    return 0


if __name__ == '__main__':
    sys.exit(main())
