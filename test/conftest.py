"""Shared test set-up: a ROS domain of this run's own, discovery kept on localhost, stale Fast DDS
segments removed from /dev/shm before the session."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from ros_helpers.shm import remove_stale

ROOT = Path(__file__).resolve().parents[1]

# Each test run gets its own DDS domain (set before any rclpy.init in this process and
# inherited by every node process the tests start), so parallel runs never hear each other.
os.environ['ROS_DOMAIN_ID'] = os.environ.get('HRN_TEST_DOMAIN_ID', str(1 + os.getpid() % 100))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')


_STALE = pytest.StashKey[int]()


def pytest_sessionstart(session: pytest.Session) -> None:
    """Remove this user's stale Fast DDS segments (``ros_helpers/shm.py``)."""
    session.config.stash[_STALE] = remove_stale()


def pytest_report_header(config: pytest.Config) -> str | None:
    n = config.stash.get(_STALE, 0)
    return f'removed {n} stale Fast DDS segments from /dev/shm' if n else None


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator; tests that need several streams spawn from it."""
    return np.random.default_rng(12345)
