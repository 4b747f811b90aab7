"""The reported pose: unwrap against the last tracked pose, hold, and the map's origin."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrn_vo_ros.core.hrn.pose import ReportedPose
from hrn_vo_ros.core.hrn.shared import FactorCodebook


def book(name: str, period: float | None, unit: float, sign: float = 1.0) -> FactorCodebook:
    vals = np.arange(8.0)
    return FactorCodebook(name, vals, vals, period, unit, sign)


#: a 128-px toroidal h (sign -1 as the network's), a 100-px v, a roll of 192 samples
BOOKS = {'h': book('h', 128.0, 1.0, -1.0), 'v': book('v', 100.0, 1.0),
         'r': book('r', 192.0, 2.0 * math.pi / 192.0)}


def test_a_periodic_readout_unwraps_against_the_last_tracked_pose() -> None:
    p = ReportedPose()
    p.update({'h': -60.0, 'v': 10.0, 'r': 90.0}, BOOKS, hold=False, tracking=True)
    # h crosses the canvas seam: index +62 is 6 px further from 60, not 122 px back
    out = p.update({'h': 62.0, 'v': 12.0, 'r': -95.0}, BOOKS, hold=False, tracking=True)
    assert out['h'] == pytest.approx(66.0)
    assert out['v'] == pytest.approx(12.0)
    assert out['r'] == pytest.approx(97.0 * 2.0 * math.pi / 192.0)


def test_a_held_frame_outputs_the_last_tracked_pose() -> None:
    p = ReportedPose()
    p.update({'h': -5.0, 'v': 3.0, 'r': 0.0}, BOOKS, hold=False, tracking=True)
    out = p.update({'h': -40.0, 'v': -20.0, 'r': 30.0}, BOOKS, hold=True, tracking=False)
    assert (out['h'], out['v'], out['r']) == (5.0, 3.0, 0.0)
    assert p.raw['h'] == 40.0            # the network's own pose still follows the readout


def test_a_new_map_composes_with_the_pose_it_starts_at() -> None:
    p = ReportedPose()
    p.origin = {'h': 1.0, 'v': 2.0, 'r': math.pi / 2.0, 'z': 0.1}
    # a shift of 3 px along the new map's x is 3 px along the output's y after a 90° roll
    got = p.compose({'h': 3.0, 'v': 0.0, 'r': 0.2, 'z': 0.05})
    assert got == pytest.approx({'h': 1.0, 'v': 5.0, 'r': math.pi / 2.0 + 0.2, 'z': 0.15})
    p.out = {'h': 7.0, 'v': -1.0, 'r': 0.3, 'z': 0.0}
    p.restart()
    assert p.origin == {'h': 7.0, 'v': -1.0, 'r': 0.3, 'z': 0.0}
    assert p.held == p.raw == dict.fromkeys(('h', 'v', 'r', 'z'), 0.0)
    out = p.update({'h': -9.0, 'v': 9.0, 'r': 0.0}, BOOKS, hold=True, tracking=False)
    assert out == {'h': 7.0, 'v': -1.0, 'r': 0.3, 'z': 0.0}     # a poor frame holds the origin
