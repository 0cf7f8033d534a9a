# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The licence, as ament_copyright checks it for a ``ros2 pkg create`` package (and a bit more).

ament_copyright is not on PyPI (``ros-jazzy-ament-copyright`` does not exist), so these are
its checks written out: a LICENSE file with the full Apache-2.0 text that package.xml and
setup.py name, and a copyright line with an SPDX identifier of that licence at the top of
every source file (Python and shell; found here independently of the script that adds
them, ``scripts/add_license_headers.py``, whose behaviour is tested below too).
"""
from __future__ import annotations

import importlib.util
import os
from pathlib import Path
import re
import subprocess
import xml.etree.ElementTree as ElementTree

import pytest

ROOT = Path(__file__).resolve().parent.parent
LICENSE = ElementTree.parse(ROOT / 'package.xml').getroot().findtext('license')
SKIP = {'.git', '.venv', 'build', 'install', 'log', '_build', '.mypy_cache', '.pytest_cache',
        '__pycache__', '.hypothesis'}
COPYRIGHT = re.compile(r'^# Copyright (\d{4})(-\d{4})? \S.*$', re.MULTILINE)

spec = importlib.util.spec_from_file_location('add_license_headers',
                                              ROOT / 'scripts' / 'add_license_headers.py')
headers = importlib.util.module_from_spec(spec)
spec.loader.exec_module(headers)


def sources() -> list[Path]:
    """Every Python file and shell script of the checkout, walked (not asked of git)."""
    found = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in SKIP and not d.endswith('.egg-info')]
        for name in files:
            path = Path(folder) / name
            if path.stat().st_size == 0:
                continue
            if name.endswith('.py') or ('.' not in name and path.read_bytes()[:64].startswith(
                    b'#!') and headers.SHELL.match(path.read_bytes().split(b'\n', 1)[0])):
                found.append(path)
    return sorted(found)


@pytest.mark.linter
def test_license_file_is_the_apache_text_the_metadata_names():
    assert LICENSE == 'Apache-2.0' == headers.LICENSE
    text = (ROOT / 'LICENSE').read_text(encoding='utf-8')
    assert text.split()[:3] == ['Apache', 'License', 'Version'] and '2.0, January 2004' in text
    assert 'TERMS AND CONDITIONS FOR USE, REPRODUCTION, AND DISTRIBUTION' in text
    assert 'END OF TERMS AND CONDITIONS' in text and len(text) > 10000  # the full text
    setup = (ROOT / 'setup.py').read_text(encoding='utf-8')
    assert f"license='{LICENSE}'" in setup
    license_element = ElementTree.parse(ROOT / 'package.xml').getroot().find('license')
    assert license_element.get('file') == 'LICENSE'


@pytest.mark.linter
def test_every_source_file_has_a_copyright_and_spdx_header():
    files = sources()
    assert len(files) > 200 and ROOT / 'dev' in files and ROOT / '.ci' / 'run' in files
    missing, wrong = [], []
    for path in files:
        head = ''.join(path.read_text(encoding='utf-8').splitlines(keepends=True)[:6])
        found = headers.SPDX.search(head)
        if not found or not COPYRIGHT.search(head):
            missing.append(str(path.relative_to(ROOT)))
        elif found.group(1) != LICENSE:
            wrong.append(f'{path.relative_to(ROOT)}: {found.group(1)}')
    assert not wrong, f'a licence other than {LICENSE}: {wrong}'
    assert not missing, (f'{len(missing)} file(s) without "# Copyright YEAR HOLDER" and '
                         f'"# SPDX-License-Identifier: {LICENSE}" in their first lines: '
                         f'{missing[:20]}; run python scripts/add_license_headers.py')


@pytest.mark.process
def test_the_script_finds_what_the_check_walks():
    """A file the check walks is one the script would give a header (git's view)."""
    walked = {p for p in sources()}
    assert walked <= set(headers.source_files()), walked - set(headers.source_files())


@pytest.mark.process
def test_the_script_adds_the_header_once_after_shebang_and_coding(tmp_path):
    files = {
        'pkg/mod.py': '"""A module."""\nX = 1\n',
        'tool.py': '#!/usr/bin/env python3\n# -*- coding: utf-8 -*-\nprint(1)\n',
        'run': '#!/usr/bin/env bash\nset -e\n',
        'empty.py': '',
        'data.yaml': 'a: 1\n',
        'done.py': '# Copyright 2019 Someone Else\n# SPDX-License-Identifier: Apache-2.0\n',
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    subprocess.run(['git', 'init', '-q'], cwd=tmp_path, check=True)
    assert headers.main(['--root', str(tmp_path), '--check']) == 1
    assert headers.main(['--root', str(tmp_path)]) == 0
    after = {name: (tmp_path / name).read_text() for name in files}
    assert after['pkg/mod.py'] == headers.HEADER + files['pkg/mod.py']
    assert after['tool.py'] == ('#!/usr/bin/env python3\n# -*- coding: utf-8 -*-\n'
                                + headers.HEADER + 'print(1)\n')
    assert after['run'] == '#!/usr/bin/env bash\n' + headers.HEADER + 'set -e\n'
    for name in ('empty.py', 'data.yaml', 'done.py'):
        assert after[name] == files[name], name
    assert headers.main(['--root', str(tmp_path)]) == 0  # again: nothing changes
    assert {name: (tmp_path / name).read_text() for name in files} == after
    assert headers.main(['--root', str(tmp_path), '--check']) == 0
