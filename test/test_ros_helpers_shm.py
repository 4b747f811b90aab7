"""The removal of stale Fast DDS shared-memory segments before a test session
(``ros_helpers/shm.py``), with this machine's real file locks."""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
import time

from ros_helpers.shm import remove_stale


def _file(d: Path, name: str, age_s: float) -> Path:
    p = d / name
    p.write_bytes(b'\0' * 64)
    t = time.time() - age_s
    os.utime(p, (t, t))
    return p


def test_only_old_segments_whose_lock_nobody_holds_go(tmp_path: Path) -> None:
    """An old segment with a free lock file goes with it; one whose lock a participant holds
    (here this process, through another open file), a young one, the port files and
    anything else stay."""
    stale = [_file(tmp_path, 'fastrtps_0a1b', 120.0), _file(tmp_path, 'fastrtps_0a1b_el', 120.0),
             _file(tmp_path, 'fastrtps_2c3d', 300.0), _file(tmp_path, 'fastrtps_2c3d_el', 300.0)]
    live = [_file(tmp_path, 'fastrtps_4e5f', 120.0), _file(tmp_path, 'fastrtps_4e5f_el', 120.0)]
    young = [_file(tmp_path, 'fastrtps_6a7b', 10.0), _file(tmp_path, 'fastrtps_6a7b_el', 10.0)]
    port = [_file(tmp_path, 'fastrtps_port7411', 120.0),
            _file(tmp_path, 'fastrtps_port7411_el', 120.0),
            _file(tmp_path, 'sem.fastrtps_port7411_mutex', 120.0)]
    other = [_file(tmp_path, 'fastrtps_8c9d', 120.0), _file(tmp_path, 'unrelated_el', 120.0)]
    fd = os.open(live[1], os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        assert remove_stale(tmp_path) == 2
    finally:
        os.close(fd)
    assert not any(p.exists() for p in stale)
    assert all(p.exists() for p in live + young + port + other)
    # once the participant is gone its segment is stale too; a longer age spares everything
    assert remove_stale(tmp_path, min_age_s=1000.0) == 0
    assert remove_stale(tmp_path) == 1 and not any(p.exists() for p in live)


def test_a_missing_directory_removes_nothing(tmp_path: Path) -> None:
    assert remove_stale(tmp_path / 'absent') == 0
