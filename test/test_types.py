# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""The type checker over the package: mypy (pinned in requirements-dev.txt, setup.cfg)."""
import configparser
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parent.parent
# What the package's typing must keep catching: a configuration read of a parameter that does
# not exist, a value of the wrong type, and a codec without decode.
SEAMS = '''
from ams_can_bridge.devices.ams.device import AmsDevice
from ams_can_bridge.devices.base import Codec
from ams_can_bridge.devices.evms3.device import Evms3Device


def banks(device: AmsDevice) -> int:
    return device.config.bank_cuont


def capacity(device: Evms3Device) -> str:
    return device.config.config_pack_capacity_ah


class NoDecode:
    arbitration_ids = frozenset({1})
    is_extended_id = False


codec: Codec = NoDecode()
'''


def mypy(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'mypy', *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)


def test_mypy_finds_no_error_in_the_package():
    result = mypy('ams_can_bridge')
    assert result.returncode == 0, result.stdout + result.stderr


def test_mypy_is_strict_about_any_and_half_typed_functions():
    config = configparser.ConfigParser()
    config.read(ROOT / 'setup.cfg')
    for option in ('warn_return_any', 'disallow_incomplete_defs', 'warn_unused_ignores'):
        assert config.getboolean('mypy', option), option


def test_mypy_sees_the_configuration_and_codec_seams(tmp_path):
    path = tmp_path / 'seams.py'
    path.write_text(SEAMS)
    result = mypy(str(path))
    out = result.stdout
    assert result.returncode == 1, out + result.stderr
    assert '"AmsConfig" has no attribute "bank_cuont"' in out, out
    assert 'Incompatible return value type (got "int | None", expected "str")' in out, out
    assert 'Incompatible types in assignment (expression has type "NoDecode", variable has ' \
        'type "Codec")' in out, out


@pytest.mark.parametrize('name', ['Evms3Config', 'Bms16StdConfig', 'Bms16Config'])
def test_a_configuration_class_name_means_one_class(name):
    # the wire forms in protocols/ are ...Settings; ...Config is the device's parameters
    found = [p.relative_to(ROOT) for p in (ROOT / 'ams_can_bridge').rglob('*.py')
             if f'class {name}(' in p.read_text() or f'class {name}:' in p.read_text()]
    assert found == [Path('ams_can_bridge/devices/generated_configs.py')], found
