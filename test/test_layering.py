"""The layer rule: the core imports no ROS or bag module; io imports no node or CLI."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / 'hrn_vo_ros'
ROS_OR_BAGS = ('rclpy', 'rosbags', 'event_camera_msgs', 'tf2_msgs', 'dvs_msgs', 'std_msgs',
               'sensor_msgs', 'geometry_msgs', 'nav_msgs', 'diagnostic_msgs', 'builtin_interfaces',
               'rosgraph_msgs', 'launch', 'launch_ros', 'ament_index_python', 'yaml',
               'hrn_vo_ros.io', 'hrn_vo_ros.nodes', 'hrn_vo_ros.cli')
ALLOWED_CORE = ('numpy', 'scipy', 'hrn_vo_ros.core', 'hrn_vo_ros.errors', '__future__')


def imported_modules(path: Path) -> list[str]:
    """Every module name a file imports (absolute names; relative ones resolved)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = path.relative_to(PKG.parent).with_suffix('').parts[:-node.level]
                names.append('.'.join(parts + ((node.module,) if node.module else ())))
            else:
                names.append(node.module or '')
    return names


def is_stdlib(name: str) -> bool:
    import sys
    return name.split('.')[0] in sys.stdlib_module_names


CORE_FILES = sorted((PKG / 'core').rglob('*.py'))


@pytest.mark.parametrize('path', CORE_FILES, ids=lambda p: str(p.relative_to(PKG)))
def test_core_imports_only_numpy_scipy_stdlib(path: Path) -> None:
    bad = [m for m in imported_modules(path)
           if m.startswith(ROS_OR_BAGS)
           or not (is_stdlib(m) or m.split('.')[0] in ('numpy', 'scipy')
                   or m.startswith(ALLOWED_CORE))]
    assert bad == [], f'{path} imports {bad}: the core may use numpy, scipy and the stdlib only'


@pytest.mark.parametrize('path', sorted((PKG / 'io').rglob('*.py')),
                         ids=lambda p: str(p.relative_to(PKG)))
def test_io_does_not_import_nodes_or_cli(path: Path) -> None:
    bad = [m for m in imported_modules(path)
           if m.startswith(('hrn_vo_ros.nodes', 'hrn_vo_ros.cli'))]
    assert bad == []


def test_the_scan_catches_a_forbidden_import(tmp_path: Path) -> None:
    """The rule can fail: a core-like file importing rclpy is reported."""
    fake = PKG / 'core' / '_layering_probe.py'
    assert not fake.exists()
    src = tmp_path / 'probe.py'
    src.write_text('import numpy\nfrom rclpy.node import Node\n')
    assert [m for m in imported_modules(src) if m.startswith(ROS_OR_BAGS)] == ['rclpy.node']
