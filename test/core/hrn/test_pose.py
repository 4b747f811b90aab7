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


def test_on_the_sphere_chart_a_new_map_composes_as_a_camera_rotation() -> None:
    """A map started after a 30° pan, on which the camera tilts by 30°: the camera is
    Ry(30°) Rx(30°), whose optical axis (0.433, -0.5, 0.75) is a swing of 41.41° about
    (0.756, 0.655, 0): pan 27.11°, tilt 31.30°, and a twist of -8.21° (by hand, with numpy
    Rodrigues matrices). The planar composition would give pan 30°, tilt 30°, roll 0."""
    f = 80.0
    p = ReportedPose(chart_focal_px=f)
    p.origin = {'h': f * math.radians(30.0), 'v': 0.0, 'r': 0.0, 'z': 0.1}
    got = p.compose({'h': 0.0, 'v': -f * math.radians(30.0), 'r': 0.0, 'z': 0.05})
    assert got['h'] / f == pytest.approx(math.radians(27.10896), abs=1e-6)
    assert -got['v'] / f == pytest.approx(math.radians(31.30273), abs=1e-6)
    assert got['r'] == pytest.approx(math.radians(-8.21321), abs=1e-6)
    assert got['z'] == pytest.approx(0.15)
    # pure rolls add and stay continuous past half a turn; pans about one axis add
    p.origin = {'h': 0.0, 'v': 0.0, 'r': 3.0, 'z': 0.0}
    assert p.compose({'h': 0.0, 'v': 0.0, 'r': 0.5, 'z': 0.0})['r'] == pytest.approx(3.5)
    p.origin = {'h': 0.0, 'v': 0.0, 'r': 0.1, 'z': 0.0}        # a roll of 2 rad on the map
    assert p.compose({'h': 0.0, 'v': 0.0, 'r': 2.0, 'z': 0.0})['r'] == pytest.approx(2.1)
    p.origin = {'h': f * 0.3, 'v': 0.0, 'r': 0.0, 'z': 0.0}
    assert p.compose({'h': f * 0.2, 'v': 0.0, 'r': 0.0, 'z': 0.0})['h'] == pytest.approx(f * 0.5)


def test_near_the_chart_centre_the_rotation_composition_is_the_planar_one() -> None:
    """Small poses after a rolled origin: the chart's composition agrees with the planar one
    (exactly after a pure roll; within 5e-5 px and rad after a 0.5 px origin shift, f = 80)."""
    chart, flat = ReportedPose(chart_focal_px=80.0), ReportedPose()
    for o, q in [({'h': 0.0, 'v': 0.0, 'r': 1.2, 'z': 0.0}, {'h': 1.5, 'v': -0.7, 'r': 0.01}),
                 ({'h': 0.4, 'v': -0.3, 'r': -2.0, 'z': 0.0}, {'h': -0.9, 'v': 1.1, 'r': -0.02})]:
        chart.origin = flat.origin = o
        a, b = chart.compose({**q, 'z': 0.0}), flat.compose({**q, 'z': 0.0})
        assert a['h'] == pytest.approx(b['h'], abs=1e-4)
        assert a['v'] == pytest.approx(b['v'], abs=1e-4)
        assert a['r'] == pytest.approx(b['r'], abs=1e-4)
