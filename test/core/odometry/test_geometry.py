"""The float fast paths of core/odometry/geometry.py against hand values and the array forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hrn_vo_ros.core.odometry.geometry import (
    compose_swing_twist,
    euler_ptr_to_matrix,
    matrix_to_euler_ptr,
    matrix_to_quat,
    matrix_to_swing_twist,
    quat_to_matrix,
    rot_x,
    rot_y,
    rot_z,
    rotation_angle,
    so3_exp,
    so3_log,
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
    R = swing_twist_to_matrix(*pan30) @ swing_twist_to_matrix(*tilt30)
    for batch in (R, np.stack([R, R, R])):      # one matrix and a batch of them
        got = np.array(matrix_to_swing_twist(batch)).reshape(3, -1).T
        np.testing.assert_allclose(got, np.tile(want, (len(got), 1)), atol=1e-7)
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



def _scipy_rotations(n: int) -> np.ndarray:
    """n random rotations (scipy, seeded) and the half turns about x, y, z and an oblique
    axis (every branch of a matrix-to-quaternion conversion, w = 0 included)."""
    half = Rotation.from_rotvec(np.pi * np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0],
                                                  [0.6, 0.0, 0.8]]))
    return np.concatenate([Rotation.random(n, random_state=3).as_matrix(), half.as_matrix()])


def test_elementary_and_euler_rotations_against_scipy() -> None:
    """rot_x/y/z and Ry(pan) Rx(tilt) Rz(roll) (intrinsic YXZ) against scipy's conversions,
    an independent implementation; the inverse within tilt in (-90°, 90°)."""
    rng = np.random.default_rng(5)
    a = rng.uniform(-3.0, 3.0, 20)
    for f, axis in ((rot_x, 'x'), (rot_y, 'y'), (rot_z, 'z')):
        np.testing.assert_allclose(f(a), Rotation.from_euler(axis, a[:, None]).as_matrix(),
                                   atol=1e-14)
    ang = np.stack([rng.uniform(-3.0, 3.0, 50), rng.uniform(-1.5, 1.5, 50),
                    rng.uniform(-3.0, 3.0, 50)], axis=1)
    R = euler_ptr_to_matrix(ang[:, 0], ang[:, 1], ang[:, 2])
    np.testing.assert_allclose(R, Rotation.from_euler('YXZ', ang).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(np.stack(matrix_to_euler_ptr(R), axis=1), ang, atol=1e-9)


def test_quaternions_against_scipy_in_every_branch() -> None:
    """matrix_to_quat (w >= 0) and quat_to_matrix against scipy on 200 random rotations and
    four half turns, in batches of any leading shape; angles and logs likewise."""
    R = _scipy_rotations(200)
    q = matrix_to_quat(R)
    ref = Rotation.from_matrix(R).as_quat()
    ref *= np.where(ref[:, 3:4] < 0, -1.0, 1.0)
    ref *= np.where(np.abs(ref[:, 3:4]) < 1e-12, np.sign(np.sum(ref * q, axis=1))[:, None], 1.0)
    np.testing.assert_allclose(q, ref, atol=1e-12)
    assert np.all(q[:, 3] >= 0.0)
    np.testing.assert_allclose(quat_to_matrix(2.0 * ref), R, atol=1e-12)    # normalised
    assert matrix_to_quat(R[:204].reshape(4, 51, 3, 3)).shape == (4, 51, 4)
    assert quat_to_matrix(ref[:204].reshape(4, 51, 4)).shape == (4, 51, 3, 3)
    rv = Rotation.from_matrix(R).as_rotvec()
    np.testing.assert_allclose(rotation_angle(R), np.linalg.norm(rv, axis=1), atol=1e-7)
    np.testing.assert_allclose(so3_log(R[:200]), rv[:200], atol=1e-7)
