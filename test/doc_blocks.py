# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The documentation's pages as tests read them: a section, a code block, its commands.

The tests that run what the README and doc/ tell a user to type take the commands from the
pages themselves, so a page and the tested command cannot drift apart.
"""
from __future__ import annotations

from pathlib import Path
import re
import shlex

ROOT = Path(__file__).resolve().parents[1]


def section(page: str, heading: str) -> str:
    """Return one '## heading' section of a page of doc/ (up to the next '## ')."""
    text = (ROOT / 'doc' / f'{page}.md').read_text()
    return text.split(f'\n## {heading}\n', 1)[1].split('\n## ', 1)[0]


def block_after(text: str, title: str, kind: str) -> str:
    """Return the first ```kind block of text after title ('' = the first of text)."""
    rest = text.split(title, 1)[1] if title else text
    return rest.split(f'```{kind}\n', 1)[1].split('```', 1)[0]


def commands(block: str) -> list[list[str]]:
    """Return the commands of a bash block (continuations joined, comments, '&' dropped)."""
    text = block.replace('\\\n', ' ')
    out = []
    for line in text.splitlines():
        line = re.sub(r'^#\s*or:\s*', '', line.strip())
        if not line or line.startswith('#'):
            continue
        out.append(shlex.split(line.split(' #', 1)[0].rstrip(' &')))
    return out
