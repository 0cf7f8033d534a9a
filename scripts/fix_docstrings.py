# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Move multi-line docstring summaries to the second line (ament pep257 convention D213).

Usage: python scripts/fix_docstrings.py FILE... (rewrites in place, prints what changed).
"""
import io
import sys
import tokenize


def fix(source: str) -> str:
    """Return source with every multi-line triple-quoted string starting on a new line."""
    lines = source.splitlines(keepends=True)
    edits = []
    toks = [t for t in tokenize.generate_tokens(io.StringIO(source).readline)
            if t.type not in (tokenize.NL, tokenize.COMMENT)]
    for i, tok in enumerate(toks):
        if tok.type != tokenize.STRING:
            continue
        # Only string *statements* (docstrings), never data such as x = """...""".
        before = toks[i - 1].type if i else tokenize.NEWLINE
        after = toks[i + 1].type if i + 1 < len(toks) else tokenize.NEWLINE
        if before not in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
                          tokenize.ENCODING) or after not in (tokenize.NEWLINE,
                                                              tokenize.ENDMARKER):
            continue
        text = tok.string
        prefix_len = len(text) - len(text.lstrip('rRbBuU'))
        body = text[prefix_len:]
        if not body.startswith('"""') or '\n' not in body:
            continue
        if body[3:4] in ('\n', '\\'):
            continue
        edits.append(tok.start)
    for row, col in reversed(edits):
        line = lines[row - 1]
        indent = ' ' * (len(line) - len(line.lstrip())) if line.strip().startswith(
            ('"""', 'r"""')) else ' ' * col
        quote_end = line.index('"""', col) + 3
        lines[row - 1] = line[:quote_end] + '\n' + indent + line[quote_end:]
    return ''.join(lines)


if __name__ == '__main__':
    for path in sys.argv[1:]:
        with open(path) as f:
            old = f.read()
        new = fix(old)
        if new != old:
            with open(path, 'w') as f:
                f.write(new)
            print('fixed', path)
