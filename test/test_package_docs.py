# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The documentation: doc/ builds without a warning (with ROS and without), links resolve.

The build is ``sphinx-build -W -n`` (warnings are errors, every reference checked) in a
temporary directory; the generated pages must hold what the code offers today (parameters,
topics and services, each executable's --help), and the topics/services table must be what a
running bridge with every device type offers.
"""
from __future__ import annotations

import html
import importlib.metadata
import os
from pathlib import Path
import re
import subprocess
import sys
import textwrap

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'scripts'))
sys.path.insert(0, str(ROOT / 'doc'))

import check_links  # noqa: E402
import docgen  # noqa: E402
import interface_table  # noqa: E402

BUILD_TIMEOUT = 300  # s: a build takes a few seconds; a loaded CI machine gets slack
ROS = r'(rclpy|rcl|rmw|rosidl)\w*|\w+_(msgs|srvs|interfaces)|launch|launch_ros'
# As on the ROS build farm's rosdoc2 job: no ROS, none of the package's Python dependencies
# (PyYAML stays: Sphinx's MyST needs it, and the farm's image has it).
NO_DEPENDENCIES = ROS + r'|can|cantools|serial|rosbags'
# A Python start-up hook that makes these packages unimportable (the doc build's generators
# run as processes of their own: they inherit it through PYTHONPATH).
HIDE = textwrap.dedent('''
    import re, sys

    class Hide:
        @staticmethod
        def find_spec(name, path=None, target=None):
            if re.fullmatch(%r, name.split('.')[0]):
                raise ModuleNotFoundError(f'No module named {name!r}', name=name)
            return None

    sys.meta_path.insert(0, Hide)
''')


def sphinx(out: Path, strict: bool = True, hide: str | None = None) -> subprocess.Popen:
    """Start building doc/ into out/xml (docutils XML: the pages' text, unwrapped)."""
    env = dict(os.environ)
    if hide:
        (out / 'hook').mkdir(parents=True)
        (out / 'hook' / 'sitecustomize.py').write_text(HIDE % hide)
        env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(out / 'hook'),
                                                          env.get('PYTHONPATH')]))
    return subprocess.Popen(
        # --no-color: CI may force colour (FORCE_COLOR), which wraps each warning in escapes.
        [sys.executable, '-m', 'sphinx', *(['-W'] if strict else []), '-n', '--keep-going',
         '--no-color', '-q', '-b', 'xml', '-d', str(out / 'doctrees'), str(ROOT / 'doc'),
         str(out / 'xml')],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env)


def finished(build: subprocess.Popen) -> str:
    """Wait for a build; return its stderr (its warnings) after checking it succeeded."""
    _, err = build.communicate(timeout=BUILD_TIMEOUT)
    assert build.returncode == 0, err
    return err


@pytest.fixture(scope='module')
def built(tmp_path_factory) -> Path:
    """Build once for the module's checks; fail on any warning."""
    out = tmp_path_factory.mktemp('docs')
    warnings = finished(sphinx(out))
    assert 'WARNING' not in warnings, warnings
    return out / 'xml'


def page(built: Path, name: str) -> str:
    """Return the docutils XML of one built page, escapes undone (literals: <literal>)."""
    return html.unescape((built / f'{name}.xml').read_text(encoding='utf-8'))


def first_column(markdown: str) -> list[str]:
    """Return the code-quoted first cell of every table row of some Markdown."""
    return re.findall(r'^\| `([^`]+)` \|', markdown, re.MULTILINE)


def test_docs_build_without_a_warning_and_every_page_is_in_the_tree(built):
    pages = {p.stem for p in (ROOT / 'doc').glob('*.md')} | {'changelog', 'index'}
    assert {p.stem for p in built.glob('*.xml')} == pages
    index = page(built, 'index')
    for title in ('Getting started', 'Running on a real bus', 'Parameter reference',
                  'Topics and services', 'Executables', 'Changelog for package ams_can_bridge'):
        assert title in index, title


def test_the_parameter_page_is_the_parameter_tables_of_the_code(built):
    text = page(built, 'parameters')
    tables = subprocess.run([sys.executable, str(ROOT / 'scripts' / 'param_table.py')],
                            capture_output=True, text=True, timeout=60, cwd=ROOT,
                            check=True).stdout
    names = first_column(tables)
    assert len(names) > 100 and 'can.interface' in names and 'ivt_s.byte_order' in names
    for name in names:
        assert f'<literal>{name}</literal>' in text, name


def test_the_executables_page_has_the_help_of_every_console_script(built):
    text = page(built, 'executables')
    declared = [name for name, _ in docgen.console_scripts(ROOT)]
    installed = sorted(e.name for e in importlib.metadata.entry_points(group='console_scripts')
                       if e.dist is not None and e.dist.name == 'ams_can_bridge')
    assert sorted(declared) == installed  # setup.py read as pip read it
    for name in set(declared) - {'ams-can-bridge'}:
        assert f'usage: {name}' in text, name
    # the second name of bridge (iproute2 has a bridge of its own) points to bridge's help
    assert 'ams-can-bridge' in declared
    assert 'The same program as bridge' in ' '.join(re.sub('<[^>]+>', '', text).split())
    assert "Use\n'ams-can-bridge' there" in text or "Use 'ams-can-bridge' there" in \
        ' '.join(text.split())
    assert 'ams, ivt_s, evms3, bms16, sma, dbc' in text  # bridge --help, from the registry


def test_the_topics_and_services_page_lists_every_service(built):
    text = page(built, 'topics_services')
    rows = [row for device_type in interface_table.registry.DEVICE_TYPES
            for variant in interface_table.variants(device_type)
            for row in interface_table.device_services(device_type, variant)]
    assert len(rows) >= 25  # every command row of every device type and variant
    for row in rows:
        assert f'<literal><name>/{row.service}</literal>' in text, row
    for topic in ('<name>/battery_state', '<name>/temperatures', '/diagnostics'):
        assert f'<literal>{topic}</literal>' in text, topic


def test_docs_build_without_ros_and_without_any_dependency(tmp_path, built):
    no_ros = sphinx(tmp_path / 'no_ros', hide=ROS)
    bare = sphinx(tmp_path / 'bare', strict=False, hide=NO_DEPENDENCIES)
    assert finished(no_ros) == ''
    warnings = finished(bare)
    probe = subprocess.run([sys.executable, '-c', 'import rclpy'], capture_output=True,
                           text=True, timeout=60, env=dict(
                               os.environ, PYTHONPATH=str(tmp_path / 'no_ros' / 'hook')))
    assert "No module named 'rclpy'" in probe.stderr  # the hook hides ROS
    # Without ROS: the same tables (Sphinx's mocks stand in for the ROS types), every
    # --help but the demo's, which needs rclpy, as its section says.
    xml = tmp_path / 'no_ros' / 'xml'
    for name in ('topics_services', 'parameters'):
        assert page(xml, name) == page(built, name), name
    executables = page(xml, 'executables')
    for name in ('bridge', 'simulator', 'log2bag'):
        assert f'usage: {name}' in executables, name
    assert ('<literal>ams_can_bridge.ros.demo:main</literal>):</paragraph>\n'
            '            <paragraph>Its <literal>--help</literal> is generated when the '
            'documentation is built with every dependency of the package installed; where this '
            'page was built, rclpy was not.') in executables
    # Without ROS and python-can, cantools, ... (rosdoc2 on the ROS build farm): the
    # same tables with mocks, the services too (the devices read no DBC when built: the
    # protocol tables are checked against msg_defs/ in the tests), and no warning.
    xml = tmp_path / 'bare' / 'xml'
    assert page(xml, 'parameters') == page(built, 'parameters')
    assert page(xml, 'topics_services') == page(built, 'topics_services')
    assert [line for line in warnings.splitlines() if 'WARNING' in line] == []
    assert 'usage: bridge' in page(xml, 'executables')  # its --help needs nothing


@pytest.mark.process  # docgen.Parts runs the generators as processes
def test_a_block_naming_no_part_or_a_failing_generator_stops_the_build(tmp_path):
    parts = docgen.Parts(ROOT)
    try:
        with pytest.raises(docgen.ExtensionError, match="no generated part 'params': use "
                           'parameters, interfaces or executables'):
            docgen.splice('# P\n\n```{generated} params\n```\n', parts)
        spliced = docgen.splice('# P\n\n```{generated} interfaces\n```\n', parts)
        assert spliced.startswith('# P\n\n| topic | type | published by |\n')
        assert '```' not in spliced
    finally:
        parts.close()
    broken = tmp_path / 'pkg'
    (broken / 'scripts').mkdir(parents=True)
    (broken / 'setup.py').write_text("setup(entry_points={'console_scripts': []})\n")
    (broken / 'package.xml').write_text('<package><exec_depend>rclpy</exec_depend></package>')
    (broken / 'scripts' / 'param_table.py').write_text('raise SystemExit("no specs here")\n')
    (broken / 'scripts' / 'interface_table.py').write_text('print("| x |")\n')
    parts = docgen.Parts(broken)
    try:
        with pytest.raises(docgen.ExtensionError, match='param_table.py exited 1: no specs'):
            parts.markdown('parameters')
    finally:
        parts.close()


def test_every_relative_link_and_anchor_resolves():
    assert check_links.check(ROOT) == []


def test_the_link_checker_finds_missing_files_anchors_and_escapes(tmp_path):
    (tmp_path / 'doc').mkdir()
    (tmp_path / 'README.md').write_text(
        '# Title\n\n## Two `words` here\n\n## Two words here\n\n'
        '[ok](#two-words-here-1) [ok](doc/page.md#a-b) [ok](https://example.invalid/x)\n'
        '[bad](#nowhere) [bad](doc/gone.md) [bad](../outside.md) [bad](doc/page.md#nope)\n')
    (tmp_path / 'doc' / 'page.md').write_text('# A b\n\n[ok](../README.md#title)\n')
    assert check_links.check(tmp_path) == [
        'README.md:7: (#nowhere) no heading makes the anchor #nowhere in README.md',
        'README.md:7: (doc/gone.md) doc/gone.md does not exist',
        'README.md:7: (../outside.md) ../outside.md is outside the package',
        'README.md:7: (doc/page.md#nope) no heading makes the anchor #nope in doc/page.md',
    ]


def test_the_interface_table_is_what_a_running_bridge_offers(rig_factory):
    # every device type once, under a name that is not its type's
    types = {'pack': 'ams', 'shunt': 'ivt_s', 'evms': 'evms3', 'bms': 'bms16', 'inv': 'sma',
             'own': 'dbc'}
    params = {'devices': list(types), **{f'{n}.type': t for n, t in types.items()},
              'own.dbc_file': str(ROOT / 'test' / 'fixtures' / 'our_bms.dbc'),
              'own.mapping_file': str(ROOT / 'test' / 'fixtures' / 'our_bms_mapping.yaml')}
    node = rig_factory(params).node
    mine = tuple(f'/{name}/' for name in types)
    services = {s.service_name: interface_table.ros_type_name(s.srv_type, 'srv')
                for s in node.services if s.service_name.startswith(mine)}
    topics = {p.topic_name: interface_table.ros_type_name(p.msg_type, 'msg')
              for p in node.publishers
              if p.topic_name.startswith(mine) or p.topic_name in ('/diagnostics', '/clock')}
    expected_services = {f'/{name}/{row.service}': row.srv_type for name, t in types.items()
                         for row in interface_table.device_services(t)}
    assert services == expected_services
    expected_topics = {f'/{name}/battery_state': interface_table.BATTERY_STATE
                       for name in types}
    expected_topics |= {f'/{name}/{suffix}': interface_table.MULTI_ARRAY
                        for name, t in types.items()
                        for suffix in interface_table.device_arrays(t)}
    # /clock only in a replay with can.replay_clock (NODE_TOPICS says so)
    expected_topics |= {topic: msg_type for topic, msg_type, _ in interface_table.NODE_TOPICS
                        if topic != '/clock'}
    assert topics == expected_topics
    tables = '\n'.join(interface_table.topics_table() + interface_table.services_table())
    for name in {*services, *topics}:
        generic = re.sub(r'^/(' + '|'.join(types) + ')/', '<name>/', name)
        assert f'`{generic}`' in tables, name


def test_the_readmes_ten_steps_are_a_page_of_the_docs(built):
    """Issue 38, 10: the HTML docs left out the README's ten steps."""
    readme = (ROOT / 'README.md').read_text()
    steps = readme.split('## From the demo to the car in ten steps\n', 1)[1].split('\n## ')[0]
    titles = re.findall(r'^\d+\. \*\*(.+?)\*\*', steps, re.MULTILINE)
    assert len(titles) == 10
    text = ' '.join(re.sub('<[^>]+>', '', page(built, 'ten_steps')).split())
    for title in titles:
        assert title.replace('`', '') in text, title
    assert 'ten_steps' in page(built, 'index')  # in the tree, on the first page
    xml = page(built, 'ten_steps')  # README's doc/ links point to the pages here
    assert 'refuri="getting_started' in xml or 'refdoc="ten_steps"' in xml, xml[:2000]


def test_wide_code_blocks_scroll_instead_of_being_cut_off():
    conf = (ROOT / 'doc' / 'conf.py').read_text()
    assert "html_css_files = ['wide_code.css']" in conf and "html_static_path = ['_static']" \
        in conf
    css = (ROOT / 'doc' / '_static' / 'wide_code.css').read_text()
    assert re.search(r'div\.highlight pre[^{]*\{[^}]*overflow-x: auto', css), css


CONFLICT_MARKER = re.compile(r'^(<{7} |>{7} |={7}$)', re.M)


def conflict_markers(text: str) -> list[str]:
    """Return the lines of ``text`` that are a merge's conflict markers."""
    return [m.group(0) for m in CONFLICT_MARKER.finditer(text)]


def test_no_file_carries_a_merge_conflict_marker():
    # A merge's leftover markers rendered as text in getting_started.md once, unnoticed.
    suffixes = {'.md', '.rst', '.py', '.yaml', '.yml', '.json', '.txt', '.cfg', '.ini', '.xml'}
    files = [p for p in ROOT.rglob('*') if p.is_file() and p.suffix in suffixes
             and not {'.venv', 'build', 'install', 'log', '_build', '.git'} & set(
                 p.relative_to(ROOT).parts)]
    assert len(files) > 100
    found = {str(p.relative_to(ROOT)): conflict_markers(p.read_text(errors='replace'))
             for p in files}
    assert {path: marks for path, marks in found.items() if marks} == {}


def test_the_marker_check_sees_each_marker():
    text = 'a\n<<<<<<< HEAD\nb\n=======\nc\n>>>>>>> wt-E~1\n======= not one\n'
    assert conflict_markers(text) == ['<<<<<<< ', '=======', '>>>>>>> ']
