"""Stale Fast DDS shared-memory segments in /dev/shm, removed before a test session.

Every Fast DDS participant creates a segment ``fastrtps_<id>`` in /dev/shm with a lock file
``fastrtps_<id>_el`` that it holds with ``flock`` while it lives. A node killed by a signal
leaves both behind; over many local test runs hundreds pile up (798 on a developer machine;
a fresh CI machine has none; a shutdown crash first blamed on them came back without them).
The rule is Fast DDS's own (``fastdds shm clean``, not in the PyPI wheels): a segment whose
lock file can be locked is held by no live participant. Only this user's per-participant
segments older than a minute are touched; the port files (``fastrtps_port*``, shared by every
participant of a domain) are left alone.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path
import time

SHM = Path('/dev/shm')
MIN_AGE_S = 60.0


def remove_stale(shm: Path = SHM, min_age_s: float = MIN_AGE_S) -> int:
    """Remove this user's stale Fast DDS segments (and their lock files) from ``shm``; how
    many segments went."""
    if not shm.is_dir():
        return 0
    now, uid, gone = time.time(), os.getuid(), 0
    for lock in shm.glob('fastrtps_*_el'):
        segment = lock.with_name(lock.name[:-3])
        if segment.name.startswith('fastrtps_port'):
            continue
        try:
            st = lock.stat()
            if st.st_uid != uid or now - st.st_mtime <= min_age_s:
                continue
            fd = os.open(lock, os.O_RDONLY)
        except OSError:                 # gone meanwhile, or not ours to open
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:                 # a live participant holds it
            os.close(fd)
            continue
        try:                            # (removed while holding the lock, as Fast DDS does)
            segment.unlink(missing_ok=True)
            lock.unlink(missing_ok=True)
            gone += 1
        except OSError:
            pass
        finally:
            os.close(fd)
    return gone
