"""The installed package has the ROS layout: ament marker, share/ files, lib/<pkg> executables."""

from __future__ import annotations

import filecmp
import os
from pathlib import Path

from ament_index_python.packages import get_package_prefix, get_package_share_directory

ROOT = Path(__file__).resolve().parents[1]


def test_package_is_indexed_and_shares_its_files() -> None:
    share = Path(get_package_share_directory('hrn_vo_ros'))
    assert (share / 'package.xml').is_file()
    for sub in ('config', 'launch'):
        mine = sorted(p.name for p in (ROOT / sub).glob('*') if p.is_file()) \
            if (ROOT / sub).is_dir() else []
        for name in mine:
            assert filecmp.cmp(ROOT / sub / name, share / sub / name, shallow=False), \
                f'{sub}/{name} in share/ is stale: run scripts/setup.sh'


def test_executables_are_where_ros2_run_looks() -> None:
    prefix = Path(get_package_prefix('hrn_vo_ros'))
    exe = prefix / 'lib' / 'hrn_vo_ros' / 'hrn-vo'
    assert exe.exists() and os.access(exe, os.X_OK)
