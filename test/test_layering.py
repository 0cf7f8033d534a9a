"""
The layering DESIGN.md draws, checked on the source: only ``ams_can_bridge/ros/`` imports rclpy.

Protocols, devices, the bus layer, the simulators and log2bag must run (and be tested)
without ROS; an rclpy import creeping into them would tie them to a ROS installation.
"""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / 'ams_can_bridge'
ROS_ONLY = ('rclpy', 'rcl_interfaces', 'sensor_msgs', 'diagnostic_msgs', 'std_msgs',
            'std_srvs', 'rosgraph_msgs', 'builtin_interfaces')


def ros_imports(path: Path) -> list[str]:
    """Return the ROS modules a source file imports (anywhere in it, not only at the top)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found += [n for n in names if n.split('.')[0] in ROS_ONLY]
    return found


def test_only_the_ros_package_imports_ros():
    sources = sorted(PACKAGE.rglob('*.py'))
    assert len(sources) > 30
    outside = {str(p.relative_to(PACKAGE)): ros_imports(p) for p in sources
               if 'ros' not in p.relative_to(PACKAGE).parts[:1]}
    assert {p: mods for p, mods in outside.items() if mods} == {}


def test_the_check_sees_an_import_inside_a_function(tmp_path):
    source = tmp_path / 'x.py'
    source.write_text('def f():\n    from rclpy.node import Node\n    import std_msgs.msg\n')
    assert ros_imports(source) == ['rclpy.node', 'std_msgs.msg']
