# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
``log2bag``: a CAN log -> a rosbag2 of what the bridge would have published, offline.

The log goes through the bridge's own engine with the same parameters file, on the log's
time (``offline/converter.py``; doc/architecture.md, "Data"): the bag holds what the live
bridge would have published, and every header stamp and bag time is the log's (the moment
a frame was on the bus, or the log moment the periodic work was due).

Frames before ``--start`` are decoded but not written (the first message in the window
carries the state the bus had built up); reading stops at ``--end``. Both are seconds from
the first frame of the log.

Every failure is one line and exit 2, and leaves no bag behind (the output directory is
removed): an output that exists or cannot be created, a log that is empty or not a CAN log
(no frame read, or most entries unreadable), a --start past the end of the log, rosbags
not installed. A log cut short is converted up to where it stops, and the summary says where.

This module reads the log, owns the bag directory and the command line; the engine on the
log's time and its bag sink are ``offline/converter.py``'s.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import math
import os
import shutil
import sys
import time
from typing import Sequence, TextIO, TYPE_CHECKING

from ams_can_bridge.protocols.dbc_mapping.plan import set_params_files
from ams_can_bridge.errors import ConfigError, LogFileError
from ams_can_bridge.offline import log2bag_jobs
from ams_can_bridge.offline.converter import Converter, NODE_NAME
from ams_can_bridge.offline.log2bag_jobs import default_jobs
from ams_can_bridge.offline.log_frames import LogFrames
from ams_can_bridge.offline.params_file import load_parameters

if TYPE_CHECKING:  # rosbags is imported only when a bag is written
    from ams_can_bridge.offline.bag import BagOut

PROGRESS_PERIOD = 0.2  # s between progress-bar redraws
PROGRESS_EVERY = 0x3FF  # look at the clock once per 1024 frames (mask)
STORAGE_NAMES = ('mcap', 'sqlite3')  # offline/bag.py STORAGES (imported only to write)
ROSBAGS_MISSING = (
    'log2bag writes bags with the Python package rosbags, which is not installed here ({}): '
    'pip install rosbags (in a ROS 2 workspace, rosdep install --from-paths src -y installs '
    'it: package.xml declares its rosdep key python3-rosbags-pip)')


def bag_class() -> type[BagOut]:
    """Return BagOut, or raise ConfigError saying how to install rosbags when it is missing."""
    try:
        from ams_can_bridge.offline.bag import BagOut
    except ImportError as exc:
        raise ConfigError(ROSBAGS_MISSING.format(exc)) from None
    return BagOut


@dataclass
class Summary:
    """What a conversion read and wrote."""

    frames_read: int = 0
    bad_entries: int = 0
    last_bad: str = ''
    other_records: int = 0  # records that are no frame (a .trc's status, warnings)
    other_kinds: str = ''
    stopped: str = ''
    first_stamp: float = math.nan
    last_stamp: float = math.nan
    malformed: dict[str, int] = field(default_factory=dict)
    messages: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0

    def text(self) -> str:
        """Return the summary as the command prints it."""
        known = math.isfinite(self.first_stamp) and math.isfinite(self.last_stamp)
        span = self.last_stamp - self.first_stamp if known else 0.0
        rate = self.frames_read / self.seconds if self.seconds > 0 else 0.0
        lines = [f'frames read: {self.frames_read} in {self.seconds:.2f} s ({rate:,.0f}/s)',
                 f'log time span: {span:.3f} s'
                 + (f' (from {time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(self.first_stamp))}'
                    ' UTC)' if known else ''),
                 f'bad log entries skipped: {self.bad_entries}'
                 + (f' (last: {self.last_bad})' if self.last_bad else '')
                 + (f'; {self.stopped}' if self.stopped else '')]
        if self.other_records:
            lines.append(f'records that are no frame skipped: {self.other_records} '
                         f'({self.other_kinds})')
        for name, count in self.malformed.items():
            lines.append(f'{name}: {count} malformed frame(s) dropped')
        lines.append('messages written:')
        lines += [f'  {topic}: {count}' for topic, count in sorted(self.messages.items())]
        return '\n'.join(lines)


class Progress:
    """A one-line progress bar on a terminal: frames done of total, rate, time left."""

    def __init__(self, total: int | None, stream: TextIO) -> None:
        """Draw on stream only when it is a terminal."""
        self.total = total
        self.stream = stream
        self.enabled = stream.isatty()
        self.started = time.monotonic()
        self._drawn = 0.0

    def update(self, done: int, force: bool = False) -> None:
        """Redraw at most every PROGRESS_PERIOD (or now when force)."""
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._drawn < PROGRESS_PERIOD:
            return
        self._drawn = now
        elapsed = max(now - self.started, 1e-9)
        rate = done / elapsed
        if self.total:
            share = min(done / self.total, 1.0)
            bar = '#' * int(share * 30)
            left = (self.total - done) / rate if rate > 0 and done < self.total else 0.0
            text = (f'\r[{bar:<30}] {done:,} of ~{self.total:,} frames  {rate:,.0f}/s  '
                    f'{left:.1f} s left ')
        else:
            text = f'\r{done:,} frames  {rate:,.0f}/s '
        self.stream.write(text)
        self.stream.flush()

    def finish(self, done: int) -> None:
        """Draw the final state and end the line."""
        if self.enabled:
            self.update(done, force=True)
            self.stream.write('\n')


def check_output(output: str) -> None:
    """Raise ConfigError (one line) when the bag directory cannot be created there."""
    if os.path.lexists(output):
        raise ConfigError(f'output {output!r} exists: rosbag2 writes a new directory '
                          '(remove it or choose another name)')
    parent = os.path.dirname(os.path.abspath(output))
    if not os.path.isdir(parent):
        what = 'is not a directory' if os.path.exists(parent) else 'does not exist'
        raise ConfigError(f'cannot create the bag {output!r}: {parent!r} {what} (create '
                          'it first, or choose another output)')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(f'cannot create the bag {output!r}: no permission to write in '
                          f'{parent!r} (choose another output)')


def open_bag(output: str, storage: str) -> BagOut:
    """Create the bag; raise ConfigError (one line, nothing left behind) when it fails."""
    cls = bag_class()
    try:
        return cls(output, storage)
    except Exception as exc:  # OSError, rosbags' WriterError: the reason is in the text
        remove_bag(output)
        raise ConfigError(f'cannot create the bag {output!r}: {exc}') from None


def remove_bag(output: str) -> None:
    """Remove what a failed conversion wrote (the directory log2bag created)."""
    shutil.rmtree(output, ignore_errors=True)


def check_frames(log: str, frames: LogFrames, summary: Summary, start: float | None,
                 first: float, last: float) -> None:
    """Raise LogFileError/ConfigError when the log gave nothing worth a bag."""
    read, bad = summary.frames_read, frames.bad
    last_bad = f' (last: {frames.last_bad})' if frames.last_bad else ''
    if read == 0 and bad == 0 and not frames.stopped:
        raise LogFileError(f'log file {log!r} holds no CAN frame (empty)')
    if read == 0 and bad == frames.bad_stamps:
        raise LogFileError(f'log file {log!r}: no frame with a timestamp a ROS stamp can '
                           f'hold, {bad} with one that is no time{last_bad}')
    if read == 0:
        raise LogFileError(f'log file {log!r}: no CAN frame read, {bad} unreadable '
                           f'entr{"y" if bad == 1 else "ies"}{last_bad}: is it a CAN log '
                           'in the format its suffix names?')
    if bad > read:
        raise LogFileError(f'log file {log!r}: most entries are unreadable ({bad} of '
                           f'{bad + read}){last_bad}: is it a CAN log in the format its '
                           'suffix names?')
    if not math.isfinite(summary.first_stamp) and start is None:
        raise LogFileError(f'log file {log!r} holds no data frame (only error or remote '
                           'frames): nothing to write')
    if not math.isfinite(summary.first_stamp):
        raise ConfigError(f'--start {start:g} s is past the end of the log: its frames span '
                          f'{last - first:.3f} s from the first; nothing to write')


def convert(log: str, output: str, parameters: dict, storage: str = 'mcap',
            start: float | None = None, end: float | None = None,
            progress_stream: TextIO | None = None, node_name: str = NODE_NAME) -> Summary:
    """
    Convert one log into one bag; raise ConfigError/LogFileError on unusable input.

    Nothing is left behind when it raises (a KeyboardInterrupt keeps what was written).
    """
    check_output(output)
    converter = Converter(parameters, None, f'replay:{log}', node_name)  # bad: no bag
    for name, device in converter.devices.devices.items():
        for warning in device.start_log()[1]:  # a dbc device: broken DBC messages, ...
            print(f'log2bag: warning: {name}: {warning}', file=sys.stderr)
    frames = LogFrames(log)
    try:
        bag = converter.bag = open_bag(output, storage)
    except BaseException:
        frames.close()
        raise
    try:
        summary = _convert(log, frames, converter, bag, start, end, progress_stream)
    except KeyboardInterrupt:
        raise
    except BaseException:
        remove_bag(output)
        raise
    return summary


def _convert(log: str, frames: LogFrames, converter: Converter, bag: BagOut,
             start: float | None, end: float | None,
             progress_stream: TextIO | None) -> Summary:
    summary = Summary()
    progress = Progress(frames.total, progress_stream or sys.stderr)
    started = time.monotonic()
    try:
        first = math.nan
        last = math.nan
        read = 0  # summary.frames_read, kept in a local in the loop (every frame)
        frame = converter.frame
        limit = math.inf if end is None else end
        for stamp, arbitration_id, data, is_extended_id, is_error_frame, is_remote_frame \
                in frames.frames():
            if read == 0:
                first = stamp
            if stamp - first > limit:
                break
            read += 1
            if not read & PROGRESS_EVERY:
                progress.update(read)
            if is_error_frame:
                converter.error_frames += 1
                continue
            if is_remote_frame:
                continue
            write = start is None or stamp - first >= start
            if write and math.isnan(summary.first_stamp):
                summary.first_stamp = stamp
            frame(arbitration_id, data, is_extended_id, stamp, write)
            last = stamp
        summary.frames_read = read
        check_frames(log, frames, summary, start, first, last)
        converter.finish(last)
        summary.last_stamp = last
    finally:
        frames.close()
        bag.close()
    progress.finish(summary.frames_read)
    summary.bad_entries = frames.bad
    summary.last_bad = frames.last_bad
    summary.other_records = frames.other
    summary.other_kinds = ', '.join(sorted(frames.other_kinds))
    summary.stopped = frames.stopped
    if frames.truncated:
        at = time.strftime('%Y-%m-%d %H:%M:%S', time.gmtime(last))
        summary.stopped = (f'{frames.truncated}; stopped after frame {summary.frames_read}, '
                           f'log time +{last - first:.3f} s ({at} UTC)')
    summary.malformed = {name: d.frames_malformed
                         for name, d in converter.devices.devices.items() if d.frames_malformed}
    summary.messages = dict(bag.counts)
    summary.seconds = time.monotonic() - started
    return summary


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Parse the command line: LOG OUTPUT, or LOG... --output-dir DIR."""
    parser = argparse.ArgumentParser(
        prog='log2bag', description='Convert a CAN log (.log .asc .blf .trc .csv) into a '
        'rosbag2 of the topics the bridge publishes, stamped with the log time. One log: '
        'log2bag LOG OUTPUT --params-file P. Several logs or folders of logs, side by side: '
        'log2bag LOG_OR_FOLDER... --output-dir DIR --params-file P [--jobs N] (one bag per '
        'log, DIR/<log name without suffix>).')
    parser.add_argument('paths', nargs='+', metavar='LOG',
                        help='CAN log file that python-can reads, then the bag directory to '
                        'create (must not exist); with --output-dir: logs and folders only')
    parser.add_argument('--params-file', required=True,
                        help="the bridge's parameters file (devices and their parameters)")
    parser.add_argument('--output-dir', default=None,
                        help='convert every LOG (a folder: its log files) into a bag of its '
                        'own in this existing folder')
    parser.add_argument('--jobs', type=int, default=None,
                        help='with --output-dir: logs converted side by side (default: the '
                        'cores this process may use)')
    parser.add_argument('--storage', choices=STORAGE_NAMES, default='mcap',
                        help='rosbag2 storage (default mcap)')
    parser.add_argument('--start', type=float, default=None,
                        help='s after the first frame: write from here (earlier frames are '
                        'decoded, not written)')
    parser.add_argument('--end', type=float, default=None,
                        help='s after the first frame: stop here')
    parser.add_argument('--node-name', default=NODE_NAME,
                        help='node name whose entry of the parameters file applies, and '
                        'that names the diagnostics, with its namespace as the bridge '
                        f'would have it (e.g. car2/{NODE_NAME}; default {NODE_NAME}; /** '
                        'applies to every name)')
    args = parser.parse_args(argv)
    if args.start is not None and args.end is not None and args.end < args.start:
        parser.error(f'--end {args.end:g} is before --start {args.start:g}')
    if args.jobs is not None and args.jobs < 1:
        parser.error(f'--jobs {args.jobs}: give at least 1')
    if args.output_dir is None:
        if args.jobs is not None:
            parser.error('--jobs converts several logs: give them with --output-dir DIR')
        if len(args.paths) != 2:
            parser.error(f'{len(args.paths)} path(s) without --output-dir: give one LOG and '
                         'its OUTPUT bag, or any number of logs and folders with '
                         '--output-dir DIR')
        args.log, args.output = args.paths
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run log2bag; exit 0 on success, 2 on unusable input (the message says what)."""
    args = parse_args(argv)
    set_params_files([args.params_file])  # a dbc device's files beside the params file
    try:
        parameters = load_parameters(args.params_file, args.node_name)
        if args.output_dir is not None:
            return log2bag_jobs.run(
                log2bag_jobs.expand(args.paths), args.output_dir, parameters,
                args.params_file, args.storage, args.start, args.end, args.node_name,
                args.jobs or default_jobs())
        summary = convert(args.log, args.output, parameters, args.storage, args.start,
                          args.end, node_name=args.node_name)
    except (ConfigError, LogFileError) as exc:
        print(f'log2bag: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print('log2bag: interrupted; the bag holds what was written so far', file=sys.stderr)
        return 130
    print(f'wrote {args.output} ({args.storage})')
    print(summary.text())
    if summary.stopped:
        print(f'log2bag: warning: {summary.stopped}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
