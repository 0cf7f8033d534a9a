# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The package's own executables (bridge, simulator, demo, monitor, log2bag), as tests start them.

Never a bare PATH lookup: ``bridge`` is also iproute2's /usr/sbin/bridge, which a PATH lookup
finds first when the tests run against a colcon install (whose executables are in
<prefix>/lib/ams_can_bridge/, not on PATH). A file counts only where this package installs
its console scripts, and only if it is one of this package's (it names ams_can_bridge).
"""
from __future__ import annotations

import os
from pathlib import Path
import sys
from typing import Iterable

import ams_can_bridge

PACKAGE = 'ams_can_bridge'
_OURS = (b'ams_can_bridge', b'ams-can-bridge')  # the module, or the distribution's name


def install_dirs(bin_dir: Path | None = None, prefixes: Iterable[str] | None = None,
                 package_file: str | None = None) -> list[Path]:
    """
    Return where this package's console scripts may be, in the order they are tried.

    The colcon prefix the imported package comes from (<prefix>/lib/python3.X/site-packages/
    ams_can_bridge), then the directory of this Python (a venv: ./dev setup, pip install),
    then <prefix>/lib/ams_can_bridge of every prefix on AMENT_PREFIX_PATH.
    """
    here = Path(package_file or ams_can_bridge.__file__).resolve().parent
    dirs = []
    if len(here.parents) > 3 and here.parent.name in ('site-packages', 'dist-packages'):
        dirs.append(here.parents[3] / 'lib' / PACKAGE)
    dirs.append(Path(sys.executable).parent if bin_dir is None else bin_dir)
    if prefixes is None:
        prefixes = os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
    dirs += [Path(prefix) / 'lib' / PACKAGE for prefix in prefixes if prefix]
    return list(dict.fromkeys(dirs))


def is_ours(path: Path) -> bool:
    """Tell whether an executable file is one of this package's console scripts."""
    try:
        with open(path, 'rb') as stream:
            head = stream.read(4096)
    except OSError:
        return False
    return os.access(path, os.X_OK) and any(name in head for name in _OURS)


def package_executable(name: str, bin_dir: Path | None = None,
                       prefixes: Iterable[str] | None = None,
                       package_file: str | None = None) -> str:
    """
    Return the path of this package's executable ``name``; AssertionError if none.

    bin_dir, prefixes, package_file: this Python's folder, AMENT_PREFIX_PATH and the imported
    package's __init__.py unless given (tests of the lookup give them).
    """
    dirs = install_dirs(bin_dir, prefixes, package_file)
    for folder in dirs:
        if is_ours(folder / name):
            return str(folder / name)
    raise AssertionError(
        f'the {PACKAGE} executable {name!r} is not installed where this package installs it '
        f'(looked in {", ".join(str(d) for d in dirs)}): run ./dev setup (pip install -e .) '
        'or colcon build and source install/setup.bash')


def bridge_executable() -> str:
    """Return this package's installed bridge (never PATH's: that is iproute2's bridge)."""
    return package_executable('bridge')


def probe_executable() -> str:
    """Return this package's installed probe, beside its bridge."""
    return str(Path(bridge_executable()).with_name('probe'))
