# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
What every protocol module shares: the frame type, the configuration field, the DBC loader.

Protocol code is pure Python (no rclpy, no python-can): a frame is just an ID, bytes and
a flag, so the codecs run the same in the node, the simulators, the tests and benchmarks.
"""
from __future__ import annotations

import functools
import os
from pathlib import Path
from dataclasses import dataclass
from typing import Any, NamedTuple, TYPE_CHECKING

from ams_can_bridge.errors import MalformedFrameError, MsgDefsNotFound

if TYPE_CHECKING:  # cantools is imported where a DBC is read (0.14 s of a start)
    from cantools.database.can import Database

PACKAGE = 'ams_can_bridge'

# What no battery reports, whatever the bits can carry (doc/protocols.md "Physical bounds"):
# a decoded value beyond these makes its frame malformed, like a value outside the protocol.
CELL_V_MAX = 10.0  # V: a cell (the highest chemistries stay under 5 V)
TEMP_C_MAX = 200.0  # degC: a battery, a cell, a sensor on them (cells vent far below)
ABSOLUTE_ZERO_C = -273.15  # degC: no temperature below it


class Frame(NamedTuple):
    """One classic CAN data frame, as the codecs build and read it."""

    arbitration_id: int
    data: bytes
    is_extended_id: bool = False


@dataclass(frozen=True)
class ConfigField:
    """
    One configuration value of a device, in physical units, with what the wire allows.

    The protocol module lists these once (``CONFIG_FIELDS``); its encoder validates with
    them and the ROS layer declares its parameters (ranges, descriptions) from them.
    type: float, int, bool, str (then ``choices``) or 'int[]' (then ``length``).
    """

    name: str
    type: Any
    low: float | None = None
    high: float | None = None
    step: float | None = None
    unit: str = ''
    description: str = ''
    choices: tuple[str, ...] = ()
    length: int = 0


def check_dlc(arbitration_id: int, data: bytes, expected: int | tuple[int, ...]) -> None:
    """Raise MalformedFrameError unless len(data) is one of the expected lengths."""
    lengths = (expected,) if isinstance(expected, int) else expected
    if len(data) not in lengths:
        want = ' or '.join(str(n) for n in lengths)
        raise MalformedFrameError(arbitration_id, data, f'DLC {len(data)}, expected {want}')


def msg_defs_dir() -> Path:
    """
    Find the installed msg_defs/ (colcon, pip or the source tree), wherever we run from.

    Order: $AMS_CAN_BRIDGE_MSG_DEFS, the ament index (sourced ROS workspace), the
    share/ folder next to the installed Python package (pip venv or colcon install
    space, found by walking up from this file), then the source checkout.
    """
    env = os.environ.get('AMS_CAN_BRIDGE_MSG_DEFS')
    if env:
        return Path(env)
    candidates: list[Path] = []
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory(PACKAGE)) / 'msg_defs')
    except Exception:  # not a sourced ROS environment, or the index lacks us
        pass
    here = Path(__file__).resolve()
    for parent in here.parents:
        candidates.append(parent / 'share' / PACKAGE / 'msg_defs')
    candidates.append(here.parents[2] / 'msg_defs')  # source checkout / editable install
    for path in candidates:
        if path.is_dir() and any(path.glob('*.dbc')):
            return path
    raise MsgDefsNotFound(
        'cannot find the ams_can_bridge msg_defs/ folder (DBC files); looked in: '
        + ', '.join(str(p) for p in candidates)
        + '. Install the package (colcon build or pip install .) or set AMS_CAN_BRIDGE_MSG_DEFS.')


@functools.cache
def load_dbc(name: str) -> Database:
    """Load msg_defs/<name>.dbc once per process, strictly (overlapping signals fail)."""
    import cantools  # only the tests and the probe read the shipped DBCs (check_dbc)
    return cantools.database.load_file(  # type: ignore[return-value]  # a .dbc: a CAN database
        str(msg_defs_dir() / f'{name}.dbc'), strict=True)
