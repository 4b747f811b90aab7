"""Shared test set-up: a ROS domain of this run's own, discovery kept on localhost."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

# Each test run gets its own DDS domain (set before any rclpy.init in this process and
# inherited by every node process the tests start), so parallel runs never hear each other.
os.environ['ROS_DOMAIN_ID'] = os.environ.get('HRN_TEST_DOMAIN_ID', str(1 + os.getpid() % 100))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator; tests that need several streams spawn from it."""
    return np.random.default_rng(12345)
