"""Helpers for the tests that run real rclpy nodes."""

from __future__ import annotations

from collections.abc import Callable
import time
from typing import Any


def spin_until(executor: Any, cond: Callable[[], bool], timeout: float) -> bool:
    """Spin ``executor`` until ``cond()`` holds or ``timeout`` seconds passed; the final
    ``cond()``."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and not cond():
        executor.spin_once(timeout_sec=0.02)
    return cond()
