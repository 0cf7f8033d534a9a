# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Profiles: a tested DBC and mapping shipped with the package, named instead of two paths.

``<name>.profile: foxbms2`` (or ``orion_bms2``) on a ``dbc`` device stands for the files in
``config/profiles/<profile>/`` (installed to ``share/ams_can_bridge/config/profiles``).
``profile_files`` is the one lookup: the bridge, the simulator (``--profile``) and the probe
use it. Each profile's README.md says where its DBC comes from and what it was tested on.
"""
from __future__ import annotations

from pathlib import Path

from ams_can_bridge.errors import ConfigError
from ams_can_bridge.protocols.common import msg_defs_dir

PROFILES = ('foxbms2', 'orion_bms2')
MAPPING = 'mapping.yaml'


def profiles_dir() -> Path:
    """Return the installed config/profiles/ folder (beside msg_defs/, source tree too)."""
    return msg_defs_dir().parent / 'config' / 'profiles'


def profile_files(name: str) -> tuple[Path, Path]:
    """
    Return (DBC, mapping) of a shipped profile; ConfigError naming what exists otherwise.

    The DBC is the profile folder's one ``*.dbc``, the mapping its ``mapping.yaml``.
    """
    if name not in PROFILES:
        raise ConfigError(f'profile {name!r} is not one this package ships: use one of '
                          + ', '.join(PROFILES))
    folder = profiles_dir() / name
    dbcs = sorted(folder.glob('*.dbc'))
    mapping = folder / MAPPING
    if len(dbcs) != 1 or not mapping.is_file():
        raise ConfigError(f'profile {name}: {folder} lacks its DBC or {MAPPING} (an '
                          'incomplete install: reinstall the package)')
    return dbcs[0], mapping
