"""The randomized simulator family: deterministic draws, documented ranges, splits, events."""

from __future__ import annotations

from dataclasses import replace
import math
from pathlib import Path

import numpy as np
import pytest

from hrn_vo_ros.cli.main import main
from hrn_vo_ros.core.sim.config import KINDS
from hrn_vo_ros.core.sim.family import (
    draw,
    fresh_seeds,
    FRESH_START,
    on_sensor,
    preset,
    RANGES,
    SCENE_KINDS,
    scene_of,
    simulate_draw,
    split_of,
    TUNING,
    tuning_seeds,
)
from hrn_vo_ros.errors import ConfigError
from hrn_vo_ros.io.ecd import read_calib, read_sensor_size


def _within(v: float, key: str) -> bool:
    lo, hi = RANGES[key]
    return lo - 1e-12 <= v <= hi + 1e-12


@pytest.mark.parametrize('kind', KINDS)
def test_draws_are_deterministic_and_differ(kind: str) -> None:
    assert draw(kind, 10003) == draw(kind, 10003)
    assert draw(kind, 10003) != draw(kind, 10004)
    a, b = scene_of(draw(kind, 5), 2.0), scene_of(draw(kind, 5), 2.0)
    np.testing.assert_array_equal(a.texture.image, b.texture.image)
    t = np.linspace(0.0, 2.0, 50)
    np.testing.assert_array_equal(a.motion(t)[0], b.motion(t)[0])


def test_parameters_within_documented_ranges() -> None:
    scenes = set()
    for seed in [*range(40), *fresh_seeds(20)]:
        for kind in KINDS:
            d = draw(kind, seed)
            s, c = d.config, d.calib
            assert _within(s.contrast_threshold, 'contrast_threshold')
            assert s.threshold_sigma <= RANGES['threshold_spread'][1] * s.contrast_threshold
            assert _within(s.refractory_s, 'refractory_s')
            assert _within(s.noise_rate_hz, 'noise_rate_hz')
            assert _within(s.hot_pixels, 'hot_pixels')
            assert _within(s.gyro_noise, 'gyro_noise') and _within(s.acc_bias, 'acc_bias')
            if kind == 'arm':
                assert (c.width, c.height) == (640, 480)
                assert _within(d.motion['speed'], 'arm_speed')
                continue
            scenes.add(d.scene)
            assert (c.width, c.height) == (240, 180)
            assert _within(c.fx, 'fx')
            assert _within(c.cx - 119.5, 'cx_offset') and _within(c.cy - 89.5, 'cy_offset')
            assert c.dist == (0.0,) * 5 or _within(c.dist[0], 'k1')
            assert _within(d.depth_m, f'depth_{kind}')
            m = d.motion
            assert _within(m['peak'], 'peak_deg_s' if kind == 'rotation' else 'peak_m_s')
            assert _within(len(d.pauses), 'pauses')
            assert all(_within(dur, 'pause_s') for _, dur in d.pauses)
    assert scenes == set(SCENE_KINDS)


def test_splits_are_disjoint_and_named() -> None:
    tune, fresh = set(tuning_seeds(100)), set(fresh_seeds(500))
    assert not tune & fresh
    assert tune == set(TUNING)
    assert {split_of(s) for s in tune} == {'tuning'}
    assert {split_of(s) for s in fresh} == {'fresh'}
    assert split_of(FRESH_START - 1) == 'reserved'
    assert draw('rotation', 3).split == 'tuning' and draw('rotation', 10_001).split == 'fresh'
    with pytest.raises(ConfigError):
        tuning_seeds(101)
    with pytest.raises(ConfigError, match='unknown simulation kind'):
        draw('spin', 1)


def test_preset_is_like_shapes_rotation() -> None:
    d = preset('shapes_rotation')
    assert d.seconds == 60.0 and d.kind == 'rotation' and d.scene == 'shapes'
    assert (d.calib.fx, d.calib.cy) == pytest.approx((199.09, 110.71), abs=0.01)
    assert d.calib.dist[0] == pytest.approx(-0.368, abs=1e-3)
    motion = scene_of(d, 20.0).motion
    assert isinstance(motion.peak_speed('deg_s'), float)
    with pytest.raises(ConfigError):
        preset('boxes_6dof')


def test_peak_speed_is_the_drawn_one() -> None:
    d = draw('rotation', 10_002)
    motion = scene_of(d, 5.0).motion
    assert motion.peak_speed('deg_s') == pytest.approx(d.motion['peak'], rel=0.05)


def test_drawn_sequence_obeys_sensor_size_and_refractory_period() -> None:
    seed = next(s for s in range(100, 400) if draw('rotation', s).config.refractory_s > 5e-4
                and draw('rotation', s).scene == 'shapes')
    d = draw('rotation', seed)
    quiet = replace(d, config=replace(d.config, noise_rate_hz=0.0, hot_pixels=0))
    seq = simulate_draw(quiet, 0.4)
    ev = seq.events
    assert len(ev) > 1000
    assert (seq.calib.width, seq.calib.height) == (240, 180) and seq.calib == d.calib
    assert int(ev.x.max()) < 240 and int(ev.y.max()) < 180 and int(ev.x.min()) >= 0
    assert np.all(np.diff(ev.t) >= 0) and ev.t[-1] <= 400_000_000
    pix = ev.y.astype(np.int64) * 240 + ev.x
    order = np.lexsort((ev.t, pix))
    same = pix[order][1:] == pix[order][:-1]
    dt = np.diff(ev.t[order])[same]
    assert dt.min() >= d.config.refractory_s * 1e9 - 1000    # 1 µs timestamp quantum


def test_simulate_cli_family(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'seq'
    assert main(['simulate', str(out), '--family', '--kind', 'translation', '--seconds', '0.2',
                 '--seed', '10000']) == 0
    assert 'fresh' in capsys.readouterr().out
    assert read_sensor_size(out) == (240, 180)
    assert read_calib(out).fx == pytest.approx(draw('translation', 10_000).calib.fx)


def test_on_sensor_scales_the_calibration_keeps_the_field_of_view() -> None:
    """240x180 -> 640x480: k = 8/3; a pixel centre maps to k (c + 0.5) - 0.5 (the sensor's
    corner (-0.5, -0.5) stays the corner), so the view angle of every sensor edge is kept."""
    d = draw('rotation', 10_002)
    v = on_sensor(d, 640)
    c, w = d.calib, v.calib
    assert (w.width, w.height) == (640, 480) and w.dist == c.dist
    assert w.fx == pytest.approx(c.fx * 8 / 3) and w.fy == pytest.approx(c.fy * 8 / 3)
    assert w.cx == pytest.approx(8 / 3 * (c.cx + 0.5) - 0.5)
    assert w.cy == pytest.approx(8 / 3 * (c.cy + 0.5) - 0.5)
    for edge, (a, f, n) in {'left': (c.cx, c.fx, 0), 'right': (c.cx, c.fx, 240)}.items():
        angle = math.atan((n - 0.5 - a) / f)
        scaled = math.atan((n * 8 / 3 - 0.5 - (8 / 3 * (a + 0.5) - 0.5)) / (f * 8 / 3))
        assert scaled == pytest.approx(angle), edge
    assert replace(v, calib=c) == d          # nothing else changes
    with pytest.raises(ConfigError, match='at least 16'):
        on_sensor(d, 8)
    with pytest.raises(ConfigError, match='at least 16'):
        on_sensor(d, 640, 8)


def test_on_sensor_with_a_height_crops_the_middle_rows() -> None:
    """640x360 (16:9) from 240x180: the 640x480 view without its top and bottom 60 rows, so a
    ray hits the same pixel column and a row 60 higher."""
    d = draw('rotation', 10_002)
    full, crop = on_sensor(d, 640).calib, on_sensor(d, 640, 360).calib
    assert (crop.width, crop.height) == (640, 360)
    assert (crop.fx, crop.fy, crop.cx, crop.dist) == (full.fx, full.fy, full.cx, full.dist)
    assert crop.cy == pytest.approx(full.cy - 60.0)
    assert on_sensor(d, 640, 480) == on_sensor(d, 640)
