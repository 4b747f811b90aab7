"""The gyro's binding in the HRN's coordinates and the online gyro-bias estimate."""

from __future__ import annotations

import math

from hrn_synth import event_frame, random_scene, trajectory
import numpy as np
import pytest
from test_hrn import FOCAL, gyro_between, make

from hrn_vo_ros.core.hrn.gyro import (
    chart_shift_of_rotation,
    GyroBias,
    rotation_deg,
    rotation_of_shift,
    shift_of_rotation,
)
from hrn_vo_ros.core.odometry.geometry import so3_exp


def test_shift_of_a_rotation_by_hand() -> None:
    # pan right (theta_y > 0): content moves left by f theta_y; tilt down: content moves down
    assert shift_of_rotation(np.array([0.0, 0.01, 0.0]), 100.0, 0.0, 0.5) == pytest.approx(
        {'h': -1.0, 'v': 0.0, 'r': 0.0})
    assert shift_of_rotation(np.array([0.02, 0.0, 0.1]), 100.0, 0.0, 0.5) == pytest.approx(
        {'h': 0.0, 'v': 2.0, 'r': -0.2})
    # content turned by 90 deg: the image's -1 px in x is +1 px along the map's v
    assert shift_of_rotation(np.array([0.0, 0.01, 0.0]), 100.0, math.pi / 2, 0.5) == \
        pytest.approx({'h': 0.0, 'v': 1.0, 'r': 0.0})


def test_rotation_of_a_shift_inverts_it() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        theta = rng.normal(0.0, 0.05, 3)
        alpha, unit = rng.uniform(-math.pi, math.pi), rng.uniform(0.01, 0.1)
        d = shift_of_rotation(theta, 80.0, alpha, unit)
        np.testing.assert_allclose(rotation_of_shift(d, 80.0, alpha, unit), theta, atol=1e-12)


def test_chart_binding_is_the_first_order_one_at_the_centre() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        theta = rng.normal(0.0, 1e-5, 3)
        alpha = rng.uniform(-math.pi, math.pi)
        got = chart_shift_of_rotation(theta, 80.0, 0.0, 0.0, alpha, 0.05)
        want = shift_of_rotation(theta, 80.0, alpha, 0.05)
        for k in want:      # second order: |theta|^2 f ~ 1e-8 px
            assert got[k] == pytest.approx(want[k], abs=1e-7), (k, got, want)


def test_chart_binding_of_a_large_roll_at_the_centre() -> None:
    """A 0.5 rad (28.6°) roll about the optical axis, at the chart's centre: r = -0.5 / unit,
    as the first-order binding (exact for a pure roll), h and v 0."""
    got = chart_shift_of_rotation(np.array([0.0, 0.0, 0.5]), 80.0, 0.0, 0.0, 0.3, 0.05)
    assert got['r'] == pytest.approx(-10.0, abs=1e-9)
    assert got['h'] == pytest.approx(0.0, abs=1e-9) and got['v'] == pytest.approx(0.0, abs=1e-9)


def test_chart_binding_follows_a_loop_of_pans_and_tilts() -> None:
    """Pan 30°, tilt 30°, pan back, tilt back, in 0.1° steps of the gyro: the camera does not
    come back to its first view (the loop turns it about its axis and leaves the optical axis
    off the start). The first-order binding returns to (0, 0, 0); the chart binding's
    distance from the centre is the optical axis's angle from the first one and its roll the
    twist, both from the product of the steps' rotations alone."""
    f, unit, n = 80.0, 0.02, 300
    step = math.radians(30.0) / n
    steps = ([np.array([0.0, step, 0.0])] * n + [np.array([step, 0.0, 0.0])] * n
             + [np.array([0.0, -step, 0.0])] * n + [np.array([-step, 0.0, 0.0])] * n)
    R, flat, pose = np.eye(3), np.zeros(3), np.zeros(3)
    for g in steps:
        R = R @ so3_exp(g)
        d = shift_of_rotation(g, f, flat[2] * unit, unit)
        flat += (d['h'], d['v'], d['r'])
        c = chart_shift_of_rotation(g, f, pose[0], pose[1], pose[2] * unit, unit)
        pose += (c['h'], c['v'], c['r'])
    np.testing.assert_allclose(flat, 0.0, atol=1e-9)
    # the swing-twist decomposition of the product: swing about e_z x axis, then the twist
    axis = R[:, 2]
    k = np.cross([0.0, 0.0, 1.0], axis)
    swing = so3_exp(k / np.linalg.norm(k) * math.atan2(np.linalg.norm(k), axis[2]))
    twist = swing.T @ R
    axis_deg = math.degrees(math.acos(R[2, 2]))                     # 5.43°
    twist_deg = math.degrees(math.atan2(twist[1, 0], twist[0, 0]))  # -14.38°
    assert axis_deg > 5.0 and abs(twist_deg) > 14.0
    assert math.degrees(math.hypot(pose[0], pose[1]) / f) == pytest.approx(axis_deg, abs=1e-6)
    assert math.degrees(pose[2] * unit) == pytest.approx(-twist_deg, abs=1e-6)   # r = -theta_z


def test_rotation_deg_is_the_largest_angle() -> None:
    assert rotation_deg({'h': 1.0, 'v': -3.0, 'r': 0.0}, 3.0, 0.1) == pytest.approx(45.0)
    assert rotation_deg({'h': 0.0, 'v': 0.0, 'r': -2.0}, 3.0, math.radians(30)) == \
        pytest.approx(60.0)


def test_bias_estimate_converges_in_closed_loop_and_is_bounded() -> None:
    """A tracker whose readout moves a fraction k of the way from the prediction to the truth
    (plus noise) and predicts the next frame from it with the corrected gyro: the estimate is
    U / (T + prior) of the bias, k-free (the lag carries over and cancels in the sum)."""
    rng = np.random.default_rng(1)
    bias, dt, k, omega = np.array([0.01, -0.02, 0.03]), 0.01, 0.6, np.array([0.5, -0.3, 1.0])
    est = GyroBias(memory_s=100.0, prior_s=2.0, max_rad_s=0.1)
    truth, pose = np.zeros(3), np.zeros(3)
    seen = []
    for _ in range(3000):                                  # 30 s
        truth = truth + omega * dt
        pred = pose + est.correct((omega + bias) * dt, dt)
        pose = pred + k * (truth - pred) + rng.normal(0.0, 0.003, 3)
        est.update(pose - pred, dt)
        seen.append(est.b.copy())
    # T / (T + prior): 1/3 after 1 s; 0.93 after 30 s with 100 s memory (T = 25.9 s)
    np.testing.assert_allclose(seen[99], bias / 3.0, atol=0.003)
    np.testing.assert_allclose(est.b, 0.928 * bias, atol=0.002)
    assert est.updates == 3000
    np.testing.assert_allclose(est.correct(np.array([0.1, 0.1, 0.1]), 0.5),
                               0.1 - 0.5 * est.b, atol=1e-15)
    capped = GyroBias(memory_s=10.0, prior_s=0.0, max_rad_s=0.005)
    for _ in range(100):
        capped.update(-(bias - capped.b) * dt, dt)
    np.testing.assert_allclose(capped.b, [0.005, -0.005, 0.005])
    off = GyroBias(memory_s=0.0, prior_s=1.0, max_rad_s=0.1)
    off.update(np.ones(3), 0.01)
    assert not off.enabled and est.enabled
    assert off.updates == 0 and not off.b.any()
    still = GyroBias(memory_s=10.0, prior_s=1.0, max_rad_s=0.1)
    still.update(np.ones(3), 0.0)                           # a frame of no duration: nothing
    assert still.updates == 0 and not still.b.any()


@pytest.mark.parametrize('bias', [(0.04, -0.03, 0.05), (0.0, 0.0, 0.0)])
def test_hrn_learns_the_gyro_bias_while_tracking(bias: tuple[float, float, float]) -> None:
    """Synthetic frames of a known smooth motion and a gyro with a constant bias (rad/s):
    the estimate, averaged over the last 300 of 1000 frames, is the bias (and stays near 0
    without one: a sign error in the mapping would run it into its bound)."""
    b = np.array(bias)
    hrn = make({'imu': {'enabled': True, 'bias_memory_s': 100.0, 'bias_prior_s': 0.5},
                'focal_px': FOCAL,
                'cleanup': {'gamma': 0.6}, 'map': {'mu1': 0.99, 'mu2': 0.002}})
    traj = trajectory(1000, amp_xy=8.0, amp_roll=0.3, period=250.0)
    rng = np.random.default_rng(0)
    scene = random_scene(rng)
    seen = []
    for i, pose in enumerate(traj):
        g = gyro_between(traj[i - 1], pose) + b * 0.005 if i else None
        hrn.step(event_frame(scene, tuple(pose), rng), i * 5_000_000, gyro_delta=g)
        seen.append(hrn.gyro_bias.b.copy())
        assert hrn.state == 'tracking'
    got = np.mean(seen[700:], axis=0)
    assert np.all(np.abs(got - b) <= [0.006, 0.006, 0.015]), got
