# Copyright 2026 ams_can_bridge developers
# SPDX-License-Identifier: Apache-2.0
"""
The layering of doc/architecture.md (its Layout section), checked on the source.

Only ``ams_can_bridge/ros/`` imports rclpy.

Protocols, devices, the bus layer, the simulators and log2bag must run (and be tested)
without ROS; an rclpy import creeping into them would tie them to a ROS installation. Between
the package's own layers, the pairs in ``NEVER`` must not import each other at all.
"""
from __future__ import annotations

import ast
from pathlib import Path, PurePath
import subprocess
import sys

PACKAGE = Path(__file__).resolve().parent.parent / 'ams_can_bridge'
ROS_ONLY = ('rclpy', 'rcl_interfaces', 'sensor_msgs', 'diagnostic_msgs', 'std_msgs',
            'std_srvs', 'rosgraph_msgs', 'builtin_interfaces')


def absolute_imports(source: str, filename: str = '<source>') -> list[str]:
    """Return the modules a source imports by absolute name, anywhere in it (not only on top)."""
    found = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append(node.module)
    return found


def ros_imports(path: Path) -> list[str]:
    """Return the ROS modules a source file imports (anywhere in it, not only at the top)."""
    return [n for n in absolute_imports(path.read_text(), str(path))
            if n.split('.')[0] in ROS_ONLY]


def test_only_the_ros_package_imports_ros():
    sources = sorted(PACKAGE.rglob('*.py'))
    assert len(sources) > 30
    outside = {str(p.relative_to(PACKAGE)): ros_imports(p) for p in sources
               if 'ros' not in p.relative_to(PACKAGE).parts[:1]}
    assert {p: mods for p, mods in outside.items() if mods} == {}


def test_the_engine_loads_no_ros_module_even_through_what_it_imports():
    # the node's decisions live in engine/ (startup, live, param_sets, commands, gate, core):
    # importing every one of them must not load rclpy or a message package on the way
    modules = sorted(f'ams_can_bridge.engine.{p.stem}' for p in (PACKAGE / 'engine').glob('*.py')
                     if p.stem != '__init__')
    assert {'ams_can_bridge.engine.startup', 'ams_can_bridge.engine.live',
            'ams_can_bridge.engine.param_sets', 'ams_can_bridge.engine.commands'} <= set(modules)
    code = ('import importlib, sys\n'
            f'for name in {modules!r}:\n    importlib.import_module(name)\n'
            f'print(sorted(m for m in sys.modules if m.split(".")[0] in {ROS_ONLY!r}))\n')
    result = subprocess.run([sys.executable, '-c', code], cwd=PACKAGE.parent, timeout=60,
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == '[]'


def test_the_check_sees_an_import_inside_a_function(tmp_path):
    source = tmp_path / 'x.py'
    source.write_text('def f():\n    from rclpy.node import Node\n    import std_msgs.msg\n')
    assert ros_imports(source) == ['rclpy.node', 'std_msgs.msg']


# Layers that must never import another (doc/architecture.md, Layout): the protocols are the
# bottom a device builds on, the parameters are read by devices, the devices know no engine or
# ROS, the engine no ROS, and the bus layer carries frames without knowing what they mean.
NEVER = {
    'protocols': ('devices', 'engine', 'ros', 'can_io', 'offline', 'sim'),
    'parameters': ('devices',),
    'devices': ('ros', 'engine'),
    'engine': ('ros',),
    'can_io': ('devices', 'ros'),
}


def layer_of(relative: PurePath) -> str:
    """Return the layer of a source file: its folder under the package, or its module name."""
    return relative.parts[0] if len(relative.parts) > 1 else relative.stem


def package_imports(source: str, relative: PurePath) -> list[str]:
    """Return the layers of ams_can_bridge a source imports (absolute or relative imports)."""
    found = []
    folder = list(relative.parts[:-1])
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            modules = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # from . import x, from ..devices import y
                base = '.'.join(['ams_can_bridge', *folder[:len(folder) + 1 - node.level]])
            else:
                base = ''
            module = '.'.join(m for m in (base, node.module or '') if m)
            # from ams_can_bridge import engine: the names are the modules
            modules = ([module] if module.count('.') or not node.names
                       else [f'{module}.{alias.name}' for alias in node.names])
        else:
            continue
        found += [m.split('.')[1] for m in modules
                  if m.split('.')[0] == 'ams_can_bridge' and '.' in m]
    return found


def forbidden_imports(source: str, relative: PurePath) -> list[str]:
    """Return the never-pairs a source file breaks, as 'layer -> layer'."""
    layer = layer_of(relative)
    return sorted({f'{layer} -> {target}' for target in package_imports(source, relative)
                   if target in NEVER.get(layer, ())})


def test_no_layer_imports_a_layer_it_must_never_import():
    sources = {p.relative_to(PACKAGE): p.read_text() for p in sorted(PACKAGE.rglob('*.py'))}
    assert {layer_of(r) for r in sources} >= set(NEVER)
    broken = {str(r): forbidden_imports(text, r) for r, text in sources.items()}
    assert {r: pairs for r, pairs in broken.items() if pairs} == {}


def test_no_simulator_imports_device_code():
    # A simulator plays what the device's vendor documents, not what our device code
    # believes: it may share protocols/ with the device, never devices/.
    sources = sorted((PACKAGE / 'sim').glob('*.py'))
    assert len(sources) > 8
    found = {p.name: [t for t in package_imports(p.read_text(), p.relative_to(PACKAGE))
                      if t == 'devices'] for p in sources}
    assert {name: layers for name, layers in found.items() if layers} == {}


def test_the_check_sees_a_never_pair():
    source = ('import ams_can_bridge.sim.pack\n'
              'def f():\n    from ams_can_bridge.devices.base import Device\n'
              '    from ..ros import convert\n    from ams_can_bridge import engine\n'
              '    from ams_can_bridge.errors import ProtocolError\n'
              '    from .common import Frame\n')
    assert package_imports(source, PurePath('protocols/x.py')) == [
        'sim', 'devices', 'ros', 'engine', 'errors', 'protocols']
    assert forbidden_imports(source, PurePath('protocols/x.py')) == [
        'protocols -> devices', 'protocols -> engine', 'protocols -> ros', 'protocols -> sim']
    assert forbidden_imports('from ams_can_bridge.devices.base import Device\n',
                             PurePath('parameters.py')) == ['parameters -> devices']
    assert forbidden_imports('from ams_can_bridge.devices.base import Device\n',
                             PurePath('ros/x.py')) == []


TESTS = Path(__file__).resolve().parent


def imported_tests(source: str) -> list[str]:
    """Return the test modules (``test_*``) a source file imports, anywhere in it."""
    return [n for n in absolute_imports(source) if n.split('.')[0].startswith('test_')]


def test_no_test_module_imports_another_test_module():
    # What several test files share lives in test/shared.py, the helper modules and
    # conftest.py's fixtures: a test file is never a library (pytest would collect it twice
    # under two names, and moving one test breaks another).
    sources = sorted(TESTS.glob('*.py'))
    assert len(sources) > 100
    found = {p.name: imported_tests(p.read_text()) for p in sources}
    assert {name: modules for name, modules in found.items() if modules} == {}


def test_the_test_import_check_sees_both_forms():
    source = ('import test_a\nfrom test_b.x import y\ndef f():\n    from test_c import z\n'
              'from shared import FRAMES\nimport testing\n')
    assert imported_tests(source) == ['test_a', 'test_b.x', 'test_c']


def test_every_test_file_is_named_after_one_subsystem():
    from subsystems import owners  # test/subsystems.py: what ./dev test NAME runs
    names = sorted(p.name for p in TESTS.glob('test_*.py'))
    assert len(names) > 100
    assert {name: owners(name) for name in names if len(owners(name)) != 1} == {}


def test_the_subsystem_check_sees_a_file_of_none():
    from subsystems import owners
    assert owners('test_first_hour.py') == []
    assert owners('test_bridgectl.py') == ['tools'] and owners('test_bridge_node.py') == ['bridge']
    assert owners('test_can_io.py') == ['can_io'] and owners('test_can_iox.py') == []


def test_getting_started_lists_the_subsystems_as_the_table_has_them():
    from subsystems import markdown
    page = (TESTS.parent / 'doc' / 'getting_started.md').read_text()
    quoted = page.split('<!-- loops-table -->\n', 1)[1].split('<!-- /loops-table -->', 1)[0]
    assert quoted.strip() == markdown(), (
        'doc/getting_started.md: paste `python test/subsystems.py markdown` between its '
        'loops-table markers')
