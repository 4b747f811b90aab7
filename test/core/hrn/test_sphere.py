"""The sphere correction: exact chart geometry of a rotating equidistant camera, and the HRN's
roll on a rotating camera with and without it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.hrn.config import needs_focal, ResonatorConfig, without_unset_focal
from hrn_vo_ros.core.hrn.network import HRN
from hrn_vo_ros.core.hrn.sphere import SphereWarp
from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io.yamlconfig import load_configs

F = 79.6
W, H = 96, 72
CX, CY = (W - 1) / 2, (H - 1) / 2


def project(d: np.ndarray) -> np.ndarray:
    """Equidistant projection (frame pixels about the centre) of rays d (n, 3)."""
    s = np.hypot(d[:, 0], d[:, 1])
    k = F * np.arctan2(s, d[:, 2]) / np.where(s > 0, s, 1.0)
    return np.stack([k * d[:, 0], k * d[:, 1]], axis=1)


def unproject(u: np.ndarray) -> np.ndarray:
    th = np.hypot(u[:, 0], u[:, 1]) / F
    ph = np.arctan2(u[:, 1], u[:, 0])
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=1)


def pose(swing: tuple[float, float], roll: float) -> Rotation:
    """Camera-to-first-camera rotation: swing (rotation vector in the image plane) · roll."""
    return Rotation.from_rotvec([swing[0], swing[1], 0.0]) * Rotation.from_rotvec([0, 0, roll])


def chart_position(swing: tuple[float, float]) -> tuple[float, float]:
    """(h, v): where the optical axis lands on the first camera's chart."""
    c = project(pose(swing, 0.0).apply([[0.0, 0.0, 1.0]]))[0]
    return float(c[0]), float(c[1])


@pytest.mark.parametrize(('swing', 'roll'), [((0.0, 0.0), 0.4), ((0.2, -0.1), 0.0),
                                             ((-0.25, 0.15), -0.6), ((0.05, 0.3), 1.2)])
def test_warped_pixels_are_a_rigid_transform_of_the_exact_chart_points(
        swing: tuple[float, float], roll: float) -> None:
    """c + Rot(r) (u' - centre) is the chart point the pixel sees (scipy rotations as oracle)."""
    sw = SphereWarp(W, H, F)
    flat = np.arange(W * H)
    h, v = chart_position(swing)
    x, y = sw.positions(flat, h, v, roll)
    u = np.stack([flat % W - CX, flat // W - CY], axis=1)
    exact = project(pose(swing, roll).apply(unproject(u)))
    cr, sr = np.cos(roll), np.sin(roll)
    got = np.stack([h + cr * (x - CX) - sr * (y - CY), v + sr * (x - CX) + cr * (y - CY)], 1)
    np.testing.assert_allclose(got, exact, atol=1e-9)


def test_identity_at_the_start_and_non_rigid_away_from_it() -> None:
    sw = SphereWarp(W, H, F)
    img = (np.random.default_rng(0).random((H, W)) < 0.1).astype(np.uint8)
    np.testing.assert_allclose(sw.warp(img, 0.0, 0.0, 0.0), img, atol=1e-12)
    np.testing.assert_allclose(sw.warp(img, 0.0, 0.0, 0.3), img, atol=1e-12)   # roll: rigid
    h, v = chart_position((0.0, 0.26))                                        # 15° pan
    x, y = sw.positions(np.array([int(CY) * W + int(CX), 0, W * H - 1]), h, v, 0.0)
    moved = np.hypot(x - np.array([int(CX), 0, W - 1]), y - np.array([int(CY), 0, H - 1]))
    assert moved[0] < 0.05 and moved[1] > 0.3 and moved[2] > 0.3
    inner = np.zeros((H, W))
    inner[20:50, 30:60] = img[20:50, 30:60]
    assert sw.warp(inner, h, v, 0.2).sum() == pytest.approx(inner.sum())   # splat keeps mass


def test_an_implausible_pose_passes_the_frame_unwarped() -> None:
    """A lost track reads out thousands of pixels; warping by it would send every event off the
    frame, and the frames of the next pose (the same) too: the frame must pass unchanged."""
    sw = SphereWarp(W, H, F)
    img = (np.random.default_rng(1).random((H, W)) < 0.1).astype(np.uint8)
    for h, v, r in ((-2255.0, 1489.0, 9.4), (0.0, 1.6 * F, 0.0), (np.nan, 0.0, 0.0),
                    (0.0, 0.0, np.inf)):
        np.testing.assert_array_equal(sw.warp(img, h, v, r), img)
    assert not np.array_equal(sw.warp(img, 0.0, 1.4 * F, 0.0), img)   # 80°: still warped


def test_needs_a_focal_length() -> None:
    with pytest.raises(ConfigError, match='focal_px'):
        SphereWarp(W, H, 0.0)
    with pytest.raises(ConfigError, match='focal_px'):
        HRN(from_dict(ResonatorConfig, {'sphere': {'enabled': True}}),
            rng=np.random.default_rng(0))


def test_focal_length_policy_for_callers_without_a_calibration() -> None:
    on = from_dict(ResonatorConfig, {'sphere': {'enabled': True}})
    assert needs_focal(on) and needs_focal(from_dict(ResonatorConfig, {'imu': {'enabled': True}}))
    assert not needs_focal(from_dict(ResonatorConfig, {}))
    assert not needs_focal(from_dict(ResonatorConfig, {'sphere': {'enabled': True},
                                                       'focal_px': 80.0}))
    off, why = without_unset_focal(on)
    assert not off.sphere.enabled and why is not None and 'focal_px' in why
    assert why.startswith('sphere.enabled needs focal_px') and why.endswith('sphere correction')
    both = from_dict(ResonatorConfig, {'sphere': {'enabled': True}, 'imu': {'enabled': True}})
    off, why = without_unset_focal(both)
    assert not (off.sphere.enabled or off.imu.enabled) and off.imu.gamma == both.imu.gamma
    assert why is not None and why.startswith('sphere.enabled and imu.enabled need focal_px')
    assert why.endswith('without the sphere correction and the gyro')
    kept = from_dict(ResonatorConfig, {'sphere': {'enabled': True}, 'focal_px': 80.0})
    assert without_unset_focal(kept) == (kept, None)


def render(dots: np.ndarray, rot: Rotation) -> np.ndarray:
    """Binary equidistant frame of world dots (unit vectors) seen from camera rotation rot."""
    d = rot.inv().apply(dots)
    d = d[d[:, 2] > 0.2]
    u = project(d)
    x, y = np.round(u[:, 0] + CX).astype(int), np.round(u[:, 1] + CY).astype(int)
    ok = (x >= 0) & (x < W) & (y >= 0) & (y < H)
    img = np.zeros((H, W), np.uint8)
    img[y[ok], x[ok]] = 1
    return img


def test_sphere_correction_removes_the_roll_bias_of_a_rotating_camera() -> None:
    """A camera pans/tilts up to ~17° while rolling over dots on the sphere: the rigid model's
    roll drifts with the swing; with the correction it follows the true roll."""
    rng = np.random.default_rng(3)
    z = rng.uniform(np.cos(np.radians(70)), 1.0, 2500)            # dots within 70° of the axis
    a = rng.uniform(0, 2 * np.pi, 2500)
    dots = np.stack([np.sqrt(1 - z ** 2) * np.cos(a), np.sqrt(1 - z ** 2) * np.sin(a), z], 1)
    n = 400
    t = np.arange(n) / n
    sx, sy = np.radians(14) * np.sin(2 * np.pi * t), np.radians(10) * np.sin(3 * np.pi * t)
    roll = np.radians(20) * np.sin(4 * np.pi * t)
    frames = [render(dots, pose((sx[i], sy[i]), roll[i])) for i in range(n)]
    root = Path(__file__).resolve().parents[3]
    errors = {}
    for on in (False, True):
        _, cfg = load_configs(root / 'config' / 'shapes_rotation.yaml',
                              resonator={'focal_px': F, 'sphere.enabled': on})
        hrn = HRN(cfg, rng=np.random.default_rng(0))
        r = np.array([hrn.step(f, i).r for i, f in enumerate(frames)])
        errors[on] = np.degrees(np.abs(r - roll))
    off, corrected = np.median(errors[False]), np.median(errors[True])
    # measured: median 0.27° -> 0.12°, largest 0.82° -> 0.31°
    assert corrected < 0.6 * off, (corrected, off)
    assert corrected < 0.2 and np.max(errors[True]) < 0.6, errors[True].max()
