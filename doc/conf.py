# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
Sphinx configuration of the ams_can_bridge documentation (MyST Markdown).

Built two ways: ``sphinx-build -W -n doc OUT`` from the package directory
(test/test_package_docs.py does, in the test suite), and rosdoc2, which copies ``doc/`` into a
build directory of its own and runs this file inside its generated conf.py: so nothing here
may rely on ``__file__``; the package directory is found by its package.xml. The parameter,
topic/service and executable references are generated at every build (docgen.py). The Python
API pages import only modules without rclpy, so the docs build with or without ROS installed.
"""
import sys
from pathlib import Path
import xml.etree.ElementTree as ElementTree


def _package_root() -> Path:
    """Return the directory of ams_can_bridge's package.xml (plain Sphinx or rosdoc2)."""
    here = globals().get('__file__')
    # plain sphinx-build: doc/.. ; rosdoc2: it puts the package directory on sys.path
    candidates = ([Path(here).resolve().parent.parent] if here else []) + [
        Path(entry) for entry in sys.path if entry] + [Path.cwd().parent]
    for candidate in candidates:
        manifest = candidate / 'package.xml'
        if manifest.is_file() and (candidate / 'doc' / 'docgen.py').is_file():
            if ElementTree.parse(manifest).findtext('name') == 'ams_can_bridge':
                return candidate.resolve()
    raise RuntimeError('doc/conf.py: cannot find the ams_can_bridge package directory '
                       '(build from it: sphinx-build doc OUT)')


_ROOT = _package_root()
sys.path[:0] = [str(_ROOT), str(_ROOT / 'doc')]
import docgen  # noqa: E402  (found through the path just set)

_MANIFEST = ElementTree.parse(_ROOT / 'package.xml')

project = 'ams_can_bridge'
author = 'ams_can_bridge developers'
copyright = f'the ams_can_bridge developers; license {_MANIFEST.findtext("license")}'
release = _MANIFEST.findtext('version')
version = '.'.join(release.split('.')[:2])

extensions = ['myst_parser', 'sphinx.ext.autodoc']
source_suffix = {'.rst': 'restructuredtext', '.md': 'markdown'}
root_doc = master_doc = 'index'
exclude_patterns = ['_build', 'Thumbs.db', '.DS_Store']

smartquotes = False  # --ros-args stays two hyphens, 'x' stays straight
# GitHub-style anchors for headings down to ####, so '#anchor' links work here as there
myst_heading_anchors = 4


# as rosdoc2 does: a dependency that is not installed is a mock for autodoc
autodoc_mock_imports = [m for m in docgen.dependency_modules(_ROOT) if docgen.absent(m)]
autodoc_member_order = 'bysource'
autodoc_typehints = 'description'
# Type names autodoc writes that no page of ours documents (the standard library's, and the
# packages ours builds on): they are not broken links.
nitpick_ignore_regex = [
    ('py:class', r'(can|cantools|threading|typing|collections|enum|logging)\..*'),
    ('py:class', r'(Any|Callable|Iterable|Iterator|Mapping|Sequence|Path|Frame)'),
]

html_title = f'ams_can_bridge {release}'
html_static_path = ['_static']
html_css_files = ['wide_code.css']  # wide code blocks scroll, never cut off


def setup(app):
    """Generate the reference parts at every build (docgen.py)."""
    docgen.setup(app, _ROOT)
