# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The generated parts of the documentation, made at every build so that they cannot drift.

A page asks for a part with an empty fenced block whose info string names it::

    ```{generated} parameters
    ```

``conf.py`` calls :func:`setup`: when the builder starts, every part's generator starts as a
process of its own (in parallel); Sphinx's ``source-read`` event then replaces each block
with its part's Markdown before MyST parses the page. The parts:

- ``parameters``: ``scripts/param_table.py`` (the node's parameter specs);
- ``interfaces``: ``scripts/interface_table.py`` (the devices' topics and services);
- ``executables``: every console script ``setup.py`` declares, with its ``--help``.

Where a dependency of package.xml cannot be imported (rosdoc2 on the ROS build farm installs
neither ROS nor python-can; the package's own tests install everything), the tables are made
with Sphinx's mocks for the missing modules, as rosdoc2's autodoc does; a table that still
cannot be made becomes a sentence saying so and a Sphinx warning; so does an executable whose
``--help`` needs a missing module (``demo`` needs rclpy), without the warning. A generator
failing otherwise, or a block naming no part, stops the build (``ExtensionError``).
"""
from __future__ import annotations

import ast
import importlib.util
import os
from pathlib import Path
import re
import subprocess
import sys
from typing import Any
import xml.etree.ElementTree as ElementTree

from sphinx.errors import ExtensionError
from sphinx.util import logging

TIMEOUT = 60.0  # s for any one generator (each takes about a second)
HELP_COLUMNS = '100'  # argparse wraps --help to $COLUMNS: the same text on every machine
MISSING = 3  # a generator's exit code: it needs a module that is not installed (stdout: which)
BLOCK = re.compile(r'^```\{generated\}[ \t]*(\S*)[ \t]*\n```[ \t]*$', re.MULTILINE)
# A generator's process: python -c RUNNER MODULES table SCRIPT | help MODULE:FUNCTION NAME ...
# (MODULES: the Python modules of package.xml's dependencies, comma-separated)
RUNNER = '''
import importlib, importlib.util, runpy, sys
modules, kind, target, *args = sys.argv[1:]
needed = [name for name in modules.split(',') if name]


def absent(name):
    try:
        return importlib.util.find_spec(name) is None
    except (ImportError, ValueError):
        return True


missing = [name for name in needed if absent(name)]
try:
    if kind == 'table':
        if missing:
            from sphinx.ext.autodoc.mock import mock
            mocking = mock(missing)  # kept: the mocks last as long as this process
            mocking.__enter__()
        sys.argv = [target, *args]
        runpy.run_path(target, run_name='__main__')
    else:
        module, _, function = target.partition(':')
        sys.argv = [args[0], *args[1:]]
        sys.exit(getattr(importlib.import_module(module), function)())
except ModuleNotFoundError as exc:
    if (exc.name or '').split('.')[0] in needed:
        print((exc.name or '').split('.')[0])
        sys.exit(EXIT_MISSING)
    raise
except Exception:
    if kind == 'table' and missing:
        print(', '.join(missing))
        sys.exit(EXIT_MISSING)
    raise
'''.replace('EXIT_MISSING', str(MISSING))
logger = logging.getLogger(__name__)


def console_scripts(root: Path) -> list[tuple[str, str]]:
    """Return (name, 'module:function') of every console script setup.py declares."""
    tree = ast.parse((root / 'setup.py').read_text(encoding='utf-8'))
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'setup':
            for keyword in node.keywords:
                if keyword.arg == 'entry_points':
                    scripts = ast.literal_eval(keyword.value).get('console_scripts', [])
                    return [(name.strip(), target.strip())
                            for name, _, target in (line.partition('=') for line in scripts)]
    raise ExtensionError(f'{root / "setup.py"}: no entry_points in its setup() call')


def absent(module: str) -> bool:
    """Tell whether a module cannot be found (it is not installed, or its parent is broken)."""
    try:
        return importlib.util.find_spec(module) is None
    except (ImportError, ValueError):
        return True


def dependency_modules(root: Path) -> list[str]:
    """Return the Python module of each package.xml dependency (rosdoc2's reading of keys)."""
    manifest = ElementTree.parse(root / 'package.xml').getroot()
    keys = [e.text or '' for e in manifest if e.tag in ('depend', 'exec_depend')]
    return [key.removeprefix('python3-').removesuffix('-pip').replace('-', '_') for key in keys]


class Parts:
    """The generators' processes, started together; each part's Markdown on demand."""

    def __init__(self, root: Path) -> None:
        """Start every generator (the package imported from ``root``)."""
        env = dict(os.environ, COLUMNS=HELP_COLUMNS,
                   PYTHONPATH=os.pathsep.join(filter(None, [
                       str(root), os.environ.get('PYTHONPATH')])))
        self.scripts = console_scripts(root)
        jobs = {'parameters': ['table', str(root / 'scripts' / 'param_table.py')],
                'interfaces': ['table', str(root / 'scripts' / 'interface_table.py')]}
        # a second name of one program (ams-can-bridge for bridge): its page points to the first
        self.aliases: dict[str, str] = {}
        for name, target in self.scripts:
            first = next(other for other, aim in self.scripts if aim == target)
            if first != name:
                self.aliases[name] = first
                continue
            jobs['help:' + name] = ['help', target, name, '--help']
        modules = ','.join(dependency_modules(root))
        # as the messages name them
        self._commands = {key: str(Path(args[1]).relative_to(root)) if args[0] == 'table'
                          else f'{args[2]} --help' for key, args in jobs.items()}
        self._procs = {key: subprocess.Popen([sys.executable, '-c', RUNNER, modules, *args],
                                             cwd=root, env=env, text=True,
                                             stdout=subprocess.PIPE, stderr=subprocess.PIPE)
                       for key, args in jobs.items()}
        self._done: dict[str, tuple[int, str]] = {}

    def output(self, key: str) -> tuple[int, str]:
        """Return one generator's exit code (0 or MISSING) and output; else ExtensionError."""
        if key not in self._done:
            proc = self._procs[key]
            try:
                out, err = proc.communicate(timeout=TIMEOUT)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.communicate()
                raise ExtensionError(f'docgen: {self._commands[key]} did not end within '
                                     f'{TIMEOUT:g} s') from None
            self._done[key] = (proc.returncode, out)
            if proc.returncode not in (0, MISSING) or not out.strip():
                tail = err.strip().splitlines()[-1:] or ['no output']
                raise ExtensionError(f'docgen: {self._commands[key]} exited '
                                     f'{proc.returncode}: {tail[0]}')
        return self._done[key]

    def close(self) -> None:
        """End any generator nobody asked for."""
        for proc in self._procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.communicate()

    def markdown(self, part: str) -> str:
        """Return the Markdown of one part."""
        if part in ('parameters', 'interfaces'):
            code, text = self.output(part)
            if code == MISSING:
                return self._missing(f'This table (`{self._commands[part]}`)', text)
            return text
        if part == 'executables':
            return '\n'.join(self._executable(name, target) for name, target in self.scripts)
        raise ExtensionError(f'docgen: no generated part {part!r}: use parameters, '
                             'interfaces or executables')

    def _executable(self, name: str, target: str) -> str:
        if name in self.aliases:
            first = self.aliases[name]
            return (f'## `{name}`\n\nThe same program as [`{first}`](#{first}) (entry point '
                    f'`{target}`), under a second name: `{name} --help` is `{first}`\'s.\n')
        code, text = self.output('help:' + name)
        head = f'## `{name}`\n\n`ros2 run ams_can_bridge {name} --help` (entry point `{target}`)'
        if code == MISSING:
            # an executable that needs its run-time for --help: the page says so, no warning
            return f'{head}:\n\n' + self._missing('Its `--help`', text, warn=False)
        text = text.rstrip()
        longest = max((len(run) for run in re.findall('`+', text)), default=0)
        fence = '`' * max(3, longest + 1)
        return f'{head}:\n\n{fence}text\n{text}\n{fence}\n'

    @staticmethod
    def _missing(what: str, output: str, warn: bool = True) -> str:
        modules = output.strip().splitlines()[-1]  # the runner's last line: what is missing
        (logger.warning if warn else logger.info)(
            f'docgen: {what} not generated: {modules} not installed here')
        return (f'{what} is generated when the documentation is built with every dependency '
                f'of the package installed; where this page was built, {modules} '
                f'{"were" if "," in modules else "was"} not.\n')


def splice(text: str, parts: Parts) -> str:
    """Replace every ``{generated}`` block of a page with its part."""
    return BLOCK.sub(lambda match: parts.markdown(match.group(1)).rstrip() + '\n', text)


def setup(app: Any, root: Path) -> None:
    """Connect the generators to a Sphinx build (called from conf.py's setup)."""
    state: dict[str, Parts] = {}

    def start(app: Any) -> None:
        state['parts'] = Parts(root)

    def read(app: Any, docname: str, source: list[str]) -> None:
        if '```{generated}' in source[0]:
            source[0] = splice(source[0], state['parts'])

    def outdated(app: Any, env: Any, added: set, changed: set, removed: set) -> list[str]:
        # a page with a generated part is read again at every build: the code may have changed
        return [doc for doc in env.found_docs if doc not in added | changed
                and '```{generated}' in Path(env.doc2path(doc)).read_text(encoding='utf-8')]

    def finish(app: Any, exception: BaseException | None) -> None:
        if 'parts' in state:
            state['parts'].close()

    app.connect('builder-inited', start)
    app.connect('source-read', read)
    app.connect('env-get-outdated', outdated)
    app.connect('build-finished', finish)
