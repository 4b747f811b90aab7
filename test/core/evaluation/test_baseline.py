"""The classical baseline recovers known shifts and rolls of synthetic event frames."""

from __future__ import annotations

import math

from hrn_synth import event_frame, random_scene, trajectory
import numpy as np
import pytest
from scipy import ndimage

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.evaluation.baseline import (
    BaselineConfig,
    config_like,
    PhaseCorrelationBaseline,
    run_baseline,
)
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.hrn.network import HRN
from hrn_vo_ros.errors import ConfigError, TrackingError


@pytest.fixture(scope='module')
def scene() -> np.ndarray:
    rng = np.random.default_rng(0)
    blobs = ndimage.gaussian_filter(rng.random((500, 500)), 4)
    edges = np.abs(ndimage.sobel((blobs > np.median(blobs)).astype(float))) > 0
    return edges.astype(float)


def view(scene: np.ndarray, cx: float, cy: float, ang: float, zoom: float = 0.0,
         h: int = 72, w: int = 96) -> np.ndarray:
    """Binary frame of a camera at (cx, cy) (scene px), content rotated by +ang, zoomed."""
    ca, sa = math.cos(ang), math.sin(ang)
    M = math.exp(-zoom) * np.array([[ca, -sa], [sa, ca]])
    pc = np.array([(h - 1) / 2, (w - 1) / 2])
    c0 = np.array([250 + cy, 250 + cx])
    out = ndimage.affine_transform(scene, M, offset=c0 - M @ pc, output_shape=(h, w), order=1)
    return (out > 0.3).astype(np.uint8)


@pytest.mark.parametrize('cx, cy, ang', [(3.0, 0.0, 0.0), (-7.0, 4.0, 0.0), (0.0, 0.0, 0.2),
                                         (2.5, -3.5, -0.3)])
def test_single_registration(scene: np.ndarray, cx: float, cy: float, ang: float) -> None:
    b = PhaseCorrelationBaseline(BaselineConfig(local_steps=12, local_step_deg=2.0,
                                                max_roll_step_deg=45.0))
    b.step(view(scene, 0, 0, 0), 0)
    e = b.step(view(scene, cx, cy, ang), 1)
    # content rotated by +ang is a camera roll of -ang; h, v = camera position in the map
    assert e.r == pytest.approx(-ang, abs=math.radians(1.0))
    assert e.h == pytest.approx(cx, abs=0.5)
    assert e.v == pytest.approx(cy, abs=0.5)


def test_tracks_a_smooth_motion_with_map_updates(scene: np.ndarray) -> None:
    n = 120
    tt = np.arange(n) / 30
    cx, cy, ang = 25 * np.sin(tt), 15 * np.sin(0.7 * tt), 0.5 * np.sin(0.9 * tt)
    images = np.stack([view(scene, cx[k], cy[k], ang[k]) for k in range(n)])
    ests = run_baseline(np.arange(n) * 20_000_000, images, BaselineConfig(block_iterations=20))
    h = np.array([e.h for e in ests])
    r = np.array([e.r for e in ests])
    assert np.median(np.abs(h - cx)) < 0.5
    assert np.median(np.abs(r + ang)) < math.radians(1.0)


def test_bad_frames(scene: np.ndarray) -> None:
    b = PhaseCorrelationBaseline()
    with pytest.raises(TrackingError, match='shape'):
        b.step(np.zeros((10, 10)), 0)
    e = b.step(np.zeros((72, 96)), 0)
    assert not e.valid
    noise = (np.random.default_rng(1).random((72, 96)) < 0.5).astype(np.uint8)
    assert not b.step(noise, 1).valid  # half the pixels on: a still camera's noise, skipped
    assert b.step(view(scene, 0, 0, 0), 2).valid


@pytest.mark.parametrize('per_frame', [1, 2, 3])
def test_config_like_starts_the_map_on_the_same_frame_as_the_hrn(per_frame: int) -> None:
    # the HRN counts resonator iterations, the baseline frames: config_like converts
    rcfg = from_dict(ResonatorConfig, {'map': {'block_iterations': 10},
                                       'cleanup': {'iterations_per_frame': per_frame}})
    hrn = HRN(rcfg, rng=np.random.default_rng(0))
    base = PhaseCorrelationBaseline(config_like(rcfg))
    rng = np.random.default_rng(1)
    scene = random_scene(rng)
    frames = [event_frame(scene, tuple(p), rng) for p in trajectory(14, amp_xy=1.0)]
    first_hrn = next(i for i, f in enumerate(frames) if hrn.step(f, i).map_updated)
    first_base = next(i for i, f in enumerate(frames) if base.step(f, i).map_updated)
    assert first_hrn == first_base == 10 // per_frame


def test_config_like_passes_the_sphere_correction(scene: np.ndarray) -> None:
    rcfg = from_dict(ResonatorConfig, {'focal_px': 80.0, 'sphere': {'enabled': True}})
    bcfg = config_like(rcfg)
    assert bcfg.sphere and bcfg.focal_px == 80.0
    assert not config_like(from_dict(ResonatorConfig, {})).sphere
    with pytest.raises(ConfigError, match='focal_px'):
        PhaseCorrelationBaseline(BaselineConfig(sphere=True))
    # near the start of the chart the warp is close to the identity: a shift is still found
    b = PhaseCorrelationBaseline(bcfg)
    b.step(view(scene, 0, 0, 0), 0)
    e = b.step(view(scene, 3.0, -2.0, 0.0), 1)
    assert e.h == pytest.approx(3.0, abs=0.5) and e.v == pytest.approx(-2.0, abs=0.5)
