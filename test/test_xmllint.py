# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The XML files, as ament_xmllint checks them, and the metadata the ROS index reads.

ament_xmllint (not on PyPI: ``ros-jazzy-ament-xmllint`` does not exist) runs ``xmllint``
on every XML file and validates package.xml against the schema its ``xml-model``
instruction names. Written out here without network access to the schema: every XML file
is well-formed; package.xml names the format 3 schema and is read by catkin_pkg (the
parser bloom, rosdep and the ROS index use) with its validation on and no warning; and it
carries what the index shows: website, repository and bugtracker URLs, an author, the
licence and its file.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import xml.etree.ElementTree as ElementTree

from catkin_pkg.package import parse_package
import pytest

ROOT = Path(__file__).resolve().parent.parent
SKIP = {'.git', '.venv', 'build', 'install', 'log', '_build', '.mypy_cache', '.pytest_cache'}
SCHEMA = 'http://download.ros.org/schema/package_format3.xsd'

pytestmark = pytest.mark.linter


def xml_files() -> list[Path]:
    """Every *.xml file of the checkout."""
    found = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in SKIP and not d.endswith('.egg-info')]
        found += [Path(folder) / name for name in files if name.endswith('.xml')]
    return sorted(found)


def test_every_xml_file_is_well_formed():
    files = xml_files()
    assert ROOT / 'package.xml' in files and ROOT / 'security' / 'policy.xml' in files
    for path in files:
        ElementTree.parse(path)  # raises ParseError naming the line and column


def test_package_xml_names_the_format_3_schema_and_catkin_pkg_reads_it_cleanly():
    text = (ROOT / 'package.xml').read_text(encoding='utf-8')
    assert text.startswith('<?xml version="1.0"?>\n<?xml-model href="' + SCHEMA + '" '
                           'schematypens="http://www.w3.org/2001/XMLSchema"?>\n')
    warnings: list[str] = []
    package = parse_package(str(ROOT / 'package.xml'), warnings=warnings)
    assert warnings == []
    package.validate(warnings=warnings)  # raises InvalidPackage on an error
    assert warnings == []
    assert package.package_format == 3 and package.name == 'ams_can_bridge'


def test_package_xml_has_what_the_ros_index_shows():
    package = parse_package(str(ROOT / 'package.xml'))
    urls = {url.type: url.url for url in package.urls}
    assert set(urls) == {'website', 'repository', 'bugtracker'}
    assert all(re.fullmatch(r'https://[^\s/]+/\S*', url) for url in urls.values()), urls
    assert package.authors and all(a.name and a.email for a in package.authors)
    assert package.maintainers and all(m.email for m in package.maintainers)
    assert [str(lic) for lic in package.licenses] == ['Apache-2.0']
    assert package.licenses[0].file == 'LICENSE' and (ROOT / 'LICENSE').is_file()
