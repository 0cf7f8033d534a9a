# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Check every relative link and anchor of the package's Markdown, without the network.

Usage: python scripts/check_links.py [ROOT]; prints one line per broken link, exit 1 if any.
The files: README.md, bench/README.md and every page of doc/. A link is broken when its file (or
directory) does not exist, leaves the package, or names an anchor that no heading of a
Markdown target makes (GitHub's and MyST's heading anchors: lower case, punctuation dropped,
spaces to '-', a repeated heading gets '-1', '-2', ...). Links with a scheme (https:,
mailto:) are not followed: CI has no network. test/test_package_docs.py runs it.
"""
from __future__ import annotations

from functools import lru_cache
import os
from pathlib import Path
import re
import sys
from typing import Iterator

from markdown_it import MarkdownIt
from markdown_it.token import Token

SCHEME = re.compile(r'^[A-Za-z][A-Za-z0-9+.-]*:')
NOT_IN_SLUG = re.compile(r'[^\w\- ]')
_md = MarkdownIt('commonmark').enable('table')


def markdown_files(root: Path) -> list[Path]:
    """Return the Markdown files whose links are checked (paths as found, links unresolved)."""
    files = [root / 'README.md', root / 'bench' / 'README.md',
             *sorted(root.glob('doc/**/*.md'))]
    return [path for path in files if path.is_file() and '_build' not in path.parts]


def _walk(tokens: list[Token]) -> Iterator[Token]:
    for token in tokens:
        yield token
        if token.children:
            yield from _walk(token.children)


def slug(title: str) -> str:
    """Return the anchor GitHub (and MyST's myst_heading_anchors) gives a heading."""
    return NOT_IN_SLUG.sub('', title.strip().lower()).replace(' ', '-')


@lru_cache(maxsize=None)
def anchors(path: Path) -> frozenset[str]:
    """Return every heading anchor of a Markdown file."""
    tokens = _md.parse(path.read_text(encoding='utf-8'))
    found: set[str] = set()
    seen: dict[str, int] = {}
    for i, token in enumerate(tokens):
        if token.type != 'heading_open':
            continue
        title = ''.join(child.content for child in _walk(tokens[i + 1].children or [])
                        if child.type in ('text', 'code_inline'))
        base = slug(title)
        count = seen.get(base, 0)
        seen[base] = count + 1
        found.add(base if count == 0 else f'{base}-{count}')
    return frozenset(found)


def links(path: Path) -> Iterator[tuple[int, str]]:
    """Yield (line, target) of every link and image of a Markdown file."""
    line = 0
    for token in _walk(_md.parse(path.read_text(encoding='utf-8'))):
        if token.map:
            line = token.map[0] + 1
        if token.type == 'link_open':
            yield line, str(token.attrGet('href') or '')
        elif token.type == 'image':
            yield line, str(token.attrGet('src') or '')


def problem(root: Path, path: Path, target: str) -> str | None:
    """Say what is wrong with one link of ``path`` (None: it resolves)."""
    if SCHEME.match(target):
        return None
    file_part, _, anchor = target.partition('#')
    if file_part:
        # normpath, not resolve: a page linked into doc/ resolves its links from doc/
        goal = Path(os.path.normpath(path.parent / file_part))
        if root.resolve() not in goal.resolve().parents and goal.resolve() != root.resolve():
            return f'{file_part} is outside the package'
        if not goal.exists():
            return f'{file_part} does not exist'
    else:
        goal = path
    if anchor and goal.suffix == '.md' and anchor not in anchors(goal):
        return f'no heading makes the anchor #{anchor} in {goal.relative_to(root)}'
    return None


def check(root: Path) -> list[str]:
    """Return one line per broken link under ``root`` ([] = all resolve)."""
    root = root.absolute()
    found = []
    for path in markdown_files(root):
        for line, target in links(path):
            why = problem(root, path, target)
            if why:
                found.append(f'{path.relative_to(root)}:{line}: ({target}) {why}')
    return found


def main(argv: list[str]) -> int:
    """Print the broken links; exit 1 if there are any."""
    root = Path(argv[0]) if argv else Path(__file__).resolve().parent.parent
    found = check(root)
    print('\n'.join(found) or 'every relative link and anchor resolves')
    return 1 if found else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
