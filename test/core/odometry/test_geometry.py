"""The float fast paths of core/odometry/geometry.py against hand values and the array forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrn_vo_ros.core.odometry.geometry import (
    compose_swing_twist,
    matrix_to_swing_twist,
    so3_exp,
    swing_twist_to_matrix,
    turn_swing_twist,
)


def test_a_pan_then_a_tilt_by_hand() -> None:
    """Ry(30°) Rx(30°): optical axis (0.433, -0.5, 0.75), a swing of 41.41° about (0.756,
    0.655, 0), i.e. tilt 31.30°, pan 27.11°, and a twist of -8.21° (numpy Rodrigues by hand);
    the same as a 30° tilt turned by its rotation vector."""
    want = (math.radians(27.10896), math.radians(31.30273), math.radians(-8.21321))
    pan30, tilt30 = (math.radians(30.0), 0.0, 0.0), (0.0, math.radians(30.0), 0.0)
    assert compose_swing_twist(pan30, tilt30) == pytest.approx(want, abs=1e-7)
    assert turn_swing_twist(pan30, [math.radians(30.0), 0.0, 0.0]) == pytest.approx(want,
                                                                                    abs=1e-7)
    assert turn_swing_twist((0.0, 0.0, 0.0), [0.0, 0.0, 0.5]) == pytest.approx((0.0, 0.0, 0.5))
    assert turn_swing_twist((0.0, 0.0, 3.0), [0.0, 0.0, 0.5])[2] == pytest.approx(
        3.5 - 2.0 * math.pi)                            # roll within [-pi, pi]


@pytest.mark.parametrize('seed', [0, 1])
def test_the_float_forms_equal_the_array_forms(seed: int) -> None:
    """500 random poses (angles up to 69°, gyro turns up to 29°, tiny turns included): equal to
    the matrix products read back by matrix_to_swing_twist, within 1e-13 rad."""
    rng = np.random.default_rng(seed)
    for i in range(500):
        a0, a1, a2, b0, b1, b2 = (float(x) for x in rng.uniform(-1.2, 1.2, 6))
        a, b = (a0, a1, a2), (b0, b1, b2)
        theta = rng.uniform(-0.5, 0.5, 3) * (1e-13 if i % 50 == 0 else 1.0)
        for got, R in [(compose_swing_twist(a, b),
                        swing_twist_to_matrix(*a) @ swing_twist_to_matrix(*b)),
                       (turn_swing_twist(a, theta), swing_twist_to_matrix(*a) @ so3_exp(theta))]:
            want = np.array([float(x) for x in matrix_to_swing_twist(R)])
            diff = np.array(got) - want
            diff[2] = (diff[2] + math.pi) % (2.0 * math.pi) - math.pi
            assert np.abs(diff).max() < 1e-13, (a, b, theta, got, want)
