# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Put the copyright and SPDX licence header at the top of every source file; idempotent.

    python scripts/add_license_headers.py          # add the header where it is missing
    python scripts/add_license_headers.py --check  # list the files without it, exit 1 if any

Source files: every Python file (``*.py``) and shell script (a ``#!`` line naming sh or
bash) of the checkout that git tracks or would track (``git ls-files --cached --others
--exclude-standard``: .venv/, build/ and the like stay out), except empty files (nothing to
license). The header goes after a ``#!`` line and a coding line, before anything else::

    # Copyright 2026 ams_can_bridge developers
    # SPDX-License-Identifier: Apache-2.0

A file that names an SPDX-License-Identifier in its first lines already has one (its own
year and holder are kept): running the script again changes nothing, so it can be run again
after merging branches that add files. test/test_copyright.py checks every file has it.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import re
import subprocess
import sys

ROOT = Path(__file__).resolve().parent.parent
HOLDER = 'ams_can_bridge developers'  # package.xml's maintainer and author
YEAR = 2026
LICENSE = 'Apache-2.0'  # package.xml's <license>
HEADER = f'# Copyright {YEAR} {HOLDER}\n# SPDX-License-Identifier: {LICENSE}\n'
SPDX = re.compile(r'^# SPDX-License-Identifier: (\S+)$', re.MULTILINE)
SHELL = re.compile(rb'^#!.*\b(ba)?sh\b')
CODING = re.compile(r'^#.*coding[:=]')
LOOK = 6  # lines the header must start within (a #! line and a coding line come first)


def source_files(root: Path = ROOT) -> list[Path]:
    """Return the Python files and shell scripts of the checkout (git's view), sorted."""
    listed = subprocess.run(
        ['git', 'ls-files', '--cached', '--others', '--exclude-standard', '-z'], cwd=root,
        capture_output=True, check=True).stdout.decode().split('\0')
    found = []
    for name in filter(None, listed):
        path = root / name
        if not path.is_file() or path.stat().st_size == 0:
            continue
        if path.suffix == '.py':
            found.append(path)
        elif not path.suffix:
            with open(path, 'rb') as stream:
                if SHELL.match(stream.readline()):
                    found.append(path)
    return sorted(found)


def has_header(text: str) -> bool:
    """Tell whether a file's first lines name its licence (an SPDX line)."""
    return bool(SPDX.search(''.join(text.splitlines(keepends=True)[:LOOK])))


def with_header(text: str) -> str:
    """Return the text with the header added after any #! and coding lines (if missing)."""
    if has_header(text):
        return text
    lines = text.splitlines(keepends=True)
    keep = 0
    if lines and lines[0].startswith('#!'):
        keep = 1
    if len(lines) > keep and CODING.match(lines[keep]):
        keep += 1
    if keep and not lines[keep - 1].endswith('\n'):
        lines[keep - 1] += '\n'
    return ''.join(lines[:keep]) + HEADER + ''.join(lines[keep:])


def main(argv: list[str] | None = None) -> int:
    """Add the headers (or, with --check, list the files without one)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--check', action='store_true',
                        help='change nothing: list the files without the header, exit 1 if any')
    parser.add_argument('--root', type=Path, default=ROOT, help='the checkout (default: this)')
    args = parser.parse_args(argv)
    missing = []
    for path in source_files(args.root):
        text = path.read_text(encoding='utf-8')
        if has_header(text):
            continue
        missing.append(path)
        if not args.check:
            path.write_text(with_header(text), encoding='utf-8')
    verb = 'without the header' if args.check else 'given the header'
    for path in missing:
        print(f'{verb}: {path.relative_to(args.root)}')
    print(f'{len(missing)} file(s) {verb}')
    return 1 if args.check and missing else 0


if __name__ == '__main__':
    sys.exit(main())
