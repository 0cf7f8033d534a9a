# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Where probe writes its params file: never over the log it reads, never silently over a file.

The output is checked before probe reads or listens, so a mistake costs no listening time;
a directory as --output is one line and exit 2, not a traceback.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from ams_can_bridge.probe.main import main

LOG_TEXT = '(1.0) can0 123#00\n'


def _log(tmp_path: Path) -> Path:
    log = tmp_path / 'bus.log'
    log.write_text(LOG_TEXT)
    return log


def _one_line(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('probe: '), err
    assert 'Traceback' not in err
    return lines[0]


def test_the_input_log_is_never_overwritten(tmp_path, capsys):
    log = _log(tmp_path)
    line = _one_line(capsys, [str(log), '--output', str(log)])
    assert 'a file probe reads' in line
    assert log.read_text() == LOG_TEXT


def test_the_input_log_through_a_link_or_another_spelling_is_refused_even_with_force(
        tmp_path, capsys):
    log = _log(tmp_path)
    link = tmp_path / 'link.log'
    os.symlink(log, link)
    for output in (str(link), str(tmp_path / '.' / 'bus.log')):
        line = _one_line(capsys, [str(log), '--output', output, '--force'])
        assert 'a file probe reads' in line
    assert log.read_text() == LOG_TEXT


def test_an_existing_file_is_replaced_only_with_force(tmp_path, capsys):
    log = _log(tmp_path)
    out = tmp_path / 'params.yaml'
    out.write_text('# my own params\n')
    line = _one_line(capsys, [str(log), '--output', str(out)])
    assert 'exists' in line and '--force' in line
    assert out.read_text() == '# my own params\n'
    assert main([str(log), '--output', str(out), '--force']) == 0
    assert 'commands_allowed: false' in out.read_text()


def test_a_new_file_needs_no_force(tmp_path):
    log = _log(tmp_path)
    out = tmp_path / 'new.yaml'
    assert main([str(log), '--output', str(out)]) == 0
    assert out.is_file()


def test_a_directory_as_output_is_one_line(tmp_path, capsys):
    log = _log(tmp_path)
    folder = tmp_path / 'out'
    folder.mkdir()
    line = _one_line(capsys, [str(log), '--output', str(folder), '--force'])
    assert 'is a directory' in line and 'params.yaml' in line
    assert list(folder.iterdir()) == []
