# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
``log2bag LOG... --output-dir DIR --jobs N``: many logs side by side, one bag per log.

A conversion is a pure function of its log and the parameters file, so logs are simply
handed to ``N`` worker processes (default: the cores this process may use). Each log gets
the bag ``DIR/<log name without its suffix>`` and its own summary, printed when it is done;
a log that fails is named with its one-line reason and the others go on. The exit code is
0 when every log converted, 2 when any failed. Across machines, run one log2bag per log
(or per share of the logs) with the scheduler you have: doc/replay_record.md.
"""
from __future__ import annotations

from concurrent.futures import as_completed, ProcessPoolExecutor
import os
import sys
import time
from typing import Iterable, Sequence

from ams_can_bridge.protocols.dbc_mapping.plan import set_params_files
from ams_can_bridge.errors import ConfigError, LogFileError

# what python-can's LogReader reads (a folder given is searched for these)
LOG_SUFFIXES = ('.asc', '.blf', '.csv', '.log', '.mf4', '.trc')


def default_jobs() -> int:
    """Return the cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0)) or 1
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def expand(paths: Sequence[str]) -> list[str]:
    """
    Return the logs named: files as given, a folder's log files (by suffix, sorted).

    Raise ConfigError naming a path that does not exist or a folder without a log.
    """
    logs: list[str] = []
    for path in paths:
        if os.path.isdir(path):
            found = sorted(os.path.join(path, name) for name in os.listdir(path)
                           if name.lower().endswith(LOG_SUFFIXES)
                           and os.path.isfile(os.path.join(path, name)))
            if not found:
                raise ConfigError(f'folder {path!r} holds no log file ('
                                  + ' '.join(LOG_SUFFIXES) + ')')
            logs += found
        elif os.path.lexists(path):
            logs.append(path)
        else:
            raise ConfigError(f'log file {path!r} does not exist')
    return logs


def bag_names(logs: Sequence[str], output_dir: str) -> dict[str, str]:
    """Return log -> its bag (output_dir/<name without suffix>); ConfigError on a clash."""
    out: dict[str, str] = {}
    seen: dict[str, str] = {}
    for log in logs:
        name = os.path.splitext(os.path.basename(log))[0] or os.path.basename(log)
        if name in seen:
            raise ConfigError(f'logs {seen[name]!r} and {log!r} would both be converted into '
                              f'{os.path.join(output_dir, name)!r}: rename one, or convert '
                              'them into different --output-dir folders')
        seen[name] = log
        out[log] = os.path.join(output_dir, name)
    return out


def _one(log: str, bag: str, parameters: dict, params_file: str, storage: str,
         start: float | None, end: float | None, node_name: str) -> tuple[bool, str]:
    """Convert one log in a worker; return (converted, its summary or its reason)."""
    from ams_can_bridge.offline.log2bag import convert
    set_params_files([params_file])
    with open(os.devnull, 'w', encoding='utf-8') as quiet:  # no progress bar per worker
        try:
            summary = convert(log, bag, parameters, storage, start, end,
                              progress_stream=quiet, node_name=node_name)
        except (ConfigError, LogFileError) as exc:
            return False, str(exc)
        except Exception as exc:  # a log no reader foresaw: name it, the others go on
            return False, f'log file {log!r}: {type(exc).__name__}: {exc}'
    text = f'wrote {bag} ({storage})\n{summary.text()}'
    if summary.stopped:
        text += f'\nwarning: {summary.stopped}'
    return True, text


def run(logs: Sequence[str], output_dir: str, parameters: dict, params_file: str,
        storage: str, start: float | None, end: float | None, node_name: str,
        jobs: int) -> int:
    """Convert every log into output_dir with jobs processes; return the exit code."""
    bags = bag_names(logs, output_dir)
    if not os.path.isdir(output_dir):
        raise ConfigError(f'--output-dir {output_dir!r} is not a folder (create it first)')
    jobs = max(1, min(jobs, len(logs)))
    # Build the devices once here: a parameter error is told once, not per log, and the
    # workers forked after it inherit the imported modules and the DBC layouts loaded
    # (0.4 s a worker otherwise, most of a short log's conversion).
    from ams_can_bridge.offline.converter import Converter
    Converter(parameters, None, 'check', node_name)
    print(f'log2bag: {len(logs)} log(s) into {output_dir} with {jobs} job(s)', flush=True)
    started = time.monotonic()
    failed: list[str] = []
    args = (parameters, params_file, storage, start, end, node_name)
    if jobs == 1:
        results = ((log, _one(log, bags[log], *args)) for log in logs)
        failed = _report(results)
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(_one, log, bags[log], *args): log for log in logs}
            failed = _report((futures[f], f.result()) for f in as_completed(futures))
    done = len(logs) - len(failed)
    print(f'log2bag: {done} of {len(logs)} log(s) converted in '
          f'{time.monotonic() - started:.2f} s', flush=True)
    if failed:
        print(f'log2bag: {len(failed)} log(s) failed: ' + ', '.join(failed), file=sys.stderr)
        return 2
    return 0


def _report(results: Iterable[tuple[str, tuple[bool, str]]]) -> list[str]:
    """Print each log's summary or reason as it comes; return the logs that failed."""
    failed = []
    for log, (ok, text) in results:
        if ok:
            print(f'== {log}\n{text}', flush=True)
        else:
            failed.append(log)
            print(f'log2bag: {text}', file=sys.stderr, flush=True)
    return failed
