# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The test suite by subsystem: each test file's name says which part of the package it tests.

``test_<prefix>.py`` and ``test_<prefix>_*.py`` belong to the subsystem of ``<prefix>``;
every test file belongs to exactly one (test_package_layering.py checks it). ``./dev test
<subsystem>`` runs one subsystem's files, the loop to keep going while changing that part;
``./dev loops`` prints this table. The seconds are one full run's time per subsystem on the
2-core CI machine (2026-11-29, ``--junitxml`` summed per subsystem; the fast lane leaves out
what starts rclpy or a process), to choose a loop by, not a promise.

Run as a script: ``python test/subsystems.py files NAME`` prints NAME's files (what ``./dev
test NAME`` runs), ``python test/subsystems.py table`` the table (``markdown``: as
doc/getting_started.md has it, between its loops-table markers).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
import sys

TEST_DIR = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Subsystem:
    """One part of the package and the test files of it."""

    name: str
    prefixes: tuple[str, ...]
    covers: str
    seconds: int  # the whole subsystem, every lane, one run (see the module's docstring)
    fast_seconds: int  # the same files in the fast lane (-m "not ros and not process")

    def owns(self, filename: str) -> bool:
        """Tell whether a test file (``test_x.py``) is one of this subsystem's."""
        stem = filename.removesuffix('.py')
        return any(stem == f'test_{p}' or stem.startswith(f'test_{p}_') for p in self.prefixes)

    def files(self, folder: Path = TEST_DIR) -> list[Path]:
        """Return this subsystem's test files in ``folder``, sorted."""
        return sorted(p for p in folder.glob('test_*.py') if self.owns(p.name))


SUBSYSTEMS = (
    Subsystem('protocol', ('protocol',), 'protocols/: the codecs, frames to values and back, '
              'against the vendors\' documents', 14, 13),
    Subsystem('device', ('device',), 'devices/ without ROS: state, stale timeouts, reports, '
              'commands\' frames, sender threads, plugins', 36, 22),
    Subsystem('dbc', ('dbc',), 'the dbc device: mappings and rules on the DBC files and traces '
              'teams bring', 16, 8),
    Subsystem('pack', ('pack',), 'the pack device: sums, limits, latched events', 2, 1),
    Subsystem('engine', ('engine',), 'engine/: the one command pipeline, the gate, start-up '
              'decisions, the timer, the interleavings model', 56, 3),
    Subsystem('can_io', ('can_io',), 'can_io/: buses, the slcan reader, log readers, replay '
              'and recording', 31, 14),
    Subsystem('sim', ('sim',), 'sim/: the simulators and their scenarios', 32, 16),
    Subsystem('probe', ('probe',), 'probe/: recognising devices on a bus or a log, the params '
              'file it writes', 305, 27),
    Subsystem('log2bag', ('log2bag',), 'offline/: logs to bags, golden bags, --jobs, the own '
              'log readers against python-can\'s', 18, 13),
    Subsystem('bridge', ('bridge',), 'the running bridge (ros/): services, parameters, '
              'lifecycle, faults, start-up checks, the installed executable', 199, 25),
    Subsystem('tools', ('demo', 'monitor', 'bridgectl'), 'demo, monitor and bridgectl', 143, 0),
    Subsystem('package', ('package', 'flake8', 'pep257', 'copyright', 'xmllint', 'types'),
              'the package as a whole: docs, README, config files, layering, lanes, linters, '
              'mypy, the security policy', 97, 12),
)
BY_NAME = {s.name: s for s in SUBSYSTEMS}


def owners(filename: str) -> list[str]:
    """Return the names of the subsystems a test file belongs to (one, if it is well named)."""
    return [s.name for s in SUBSYSTEMS if s.owns(filename)]


def table(folder: Path = TEST_DIR) -> str:
    """Return the loops as ``./dev loops`` prints them."""
    rows = [f'{"./dev test NAME":<16} {"files":>5} {"all s":>6} {"fast s":>6}  covers']
    for s in SUBSYSTEMS:
        rows.append(f'{s.name:<16} {len(s.files(folder)):>5} {s.seconds:>6} '
                    f'{s.fast_seconds:>6}  {s.covers}')
    rows.append('fast lane of one subsystem: ./dev test NAME -m "not ros and not process"')
    return '\n'.join(rows)


def markdown(folder: Path = TEST_DIR) -> str:
    """Return the table doc/getting_started.md carries between its loops-table markers."""
    rows = ['| `./dev test NAME` | files | all (s) | fast (s) | covers |', '|---|---|---|---|---|']
    rows += [f'| `{s.name}` | {len(s.files(folder))} | {s.seconds} | {s.fast_seconds} | '
             f'{s.covers} |' for s in SUBSYSTEMS]
    return '\n'.join(rows)


def main(argv: list[str]) -> int:
    """Print a subsystem's files or the table; exit 2 naming the subsystems on a bad name."""
    if argv[:1] in (['table'], ['markdown']) and len(argv) == 1:
        print(table() if argv[0] == 'table' else markdown())
        return 0
    if argv[:1] == ['files'] and len(argv) == 2 and argv[1] in BY_NAME:
        print('\n'.join(str(p.relative_to(TEST_DIR.parent)) for p in BY_NAME[argv[1]].files()))
        return 0
    if argv[:1] == ['files'] and len(argv) == 2:
        print(f'./dev test {argv[1]}: no such subsystem and no such path; give one of '
              f'{", ".join(BY_NAME)} (./dev loops lists them), or test files', file=sys.stderr)
    else:
        print(f'subsystems.py {" ".join(argv)}: give "table", "markdown" or "files NAME"',
              file=sys.stderr)
    return 2


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
