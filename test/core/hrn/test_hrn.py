"""The HRN recovers known motions from synthetic event frames; fast = dense; IMU; bad inputs."""

from __future__ import annotations

from hrn_synth import event_frame, random_scene, trajectory
import numpy as np
import pytest

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.hrn import fhrr
from hrn_vo_ros.core.hrn.backends import BackendConfig, make_backend
from hrn_vo_ros.core.hrn.config import CleanupConfig, paper_config, ResonatorConfig
from hrn_vo_ros.core.hrn.network import HRN
from hrn_vo_ros.core.hrn.shared import (
    blend_state,
    cleanup_weights,
    map_block,
    map_block_ns,
    map_mu1,
    refine_exponent,
    state_gamma,
)
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.spiking.config import SpikingConfig
from hrn_vo_ros.errors import ConfigError, TrackingError

FOCAL = 80.0


def assert_close(got: np.ndarray, want: tuple[float, ...] | list[float],
                 tol: tuple[float, ...]) -> None:
    err = np.abs(np.asarray(got) - np.asarray(want))
    assert np.all(err <= np.asarray(tol)), f'got {got}, want {want}, tolerance {tol}'


def make(over: dict | None = None, seed: int = 1) -> HRN:
    return HRN(paper_config(over or {}), rng=np.random.default_rng(seed))


def gyro_between(p0: np.ndarray, p1: np.ndarray, f: float = FOCAL) -> np.ndarray:
    """The camera rotation (camera axes) that moves pose p0 to p1 in the synthetic model."""
    dpx, dpy = p1[0] - p0[0], p1[1] - p0[1]
    alpha = -p0[2]                                   # content angle = -roll
    ca, sa = np.cos(alpha), np.sin(alpha)
    dix, diy = -(ca * dpx - sa * dpy), -(sa * dpx + ca * dpy)   # image displacement Rot(α)(-Δp)
    return np.array([diy / f, -dix / f, p1[2] - p0[2]])


def track(hrn: HRN, traj: np.ndarray, seed: int = 0, imu: bool = False,
          w: int = 96, h: int = 72) -> np.ndarray:
    rng = np.random.default_rng(seed)
    scene = random_scene(rng)
    out = []
    for i, pose in enumerate(traj):
        g = gyro_between(traj[i - 1], pose) if imu and i else None
        e = hrn.step(event_frame(scene, tuple(pose), rng, width=w, height=h), i * 5_000_000,
                     gyro_delta=g)
        out.append((e.h, e.v, e.r, e.z))
    return np.array(out)


@pytest.mark.parametrize(('pose', 'tol'), [((4.0, -3.0, 0.0, 0.0), (0.5, 0.5, 0.02)),
                                           ((0.0, 0.0, 0.35, 0.0), (0.5, 0.5, 0.02)),
                                           ((-3.0, 2.0, -0.12, 0.0), (0.6, 0.6, 0.02))])
def test_recovers_a_fixed_shift_roll_or_both(pose: tuple[float, ...],
                                             tol: tuple[float, ...]) -> None:
    """Map = first frame at pose 0; then a view at a known pose: the readout is that pose."""
    traj = np.array([(0.0, 0.0, 0.0, 0.0)] + [pose] * 40)
    est = track(make({'map': {'learn': False}}), traj)
    assert_close(est[-1, :3], pose[:3], tol)


def test_tracks_continuous_shift_and_roll_with_map_learning() -> None:
    traj = trajectory(400, amp_xy=12.0, amp_roll=0.5, period=250.0)
    est = track(make({'cleanup': {'gamma': 0.6}, 'map': {'mu1': 0.99, 'mu2': 0.002}}), traj)
    err = np.abs(est[30:, :3] - traj[30:, :3])
    med = np.median(err, axis=0)
    assert med[0] < 1.0 and med[1] < 1.0 and med[2] < np.deg2rad(2.0), med


def test_roll_is_unwrapped_beyond_half_a_turn() -> None:
    n = 160
    traj = np.zeros((n + 30, 4))
    traj[:n, 2] = np.linspace(0.0, 4.0, n)          # > π: one and a bit half-turns, then hold
    traj[n:, 2] = 4.0
    est = track(make({'map': {'learn': False}}), traj)
    np.testing.assert_allclose(est[-1, 2], 4.0, atol=0.05)
    assert np.all(np.abs(np.diff(est[20:, 2])) < 0.2)


def test_scale_factor_recovers_zoom() -> None:
    traj = np.array([(0.0, 0.0, 0.0, 0.0)] + [(2.0, -1.0, 0.1, 0.15)] * 40)
    est = track(make({'scale': {'enabled': True}, 'map': {'learn': False}}), traj)
    assert_close(est[-1], [2.0, -1.0, 0.1, 0.15], (0.6, 0.6, 0.03, 0.03))


def test_velocity_prediction_tracks_faster_motion_more_precisely() -> None:
    """The constant-velocity prediction (cleanup.predict_velocity) moves the states ahead by
    the smoothed readout change per frame: on fast synthetic motion the readout lags less."""
    traj = trajectory(200, amp_xy=10.0, amp_roll=0.4, period=60.0)
    base = {'cleanup': {'gamma': 0.9, 'iterations_per_frame': 1}, 'map': {'learn': False}}
    plain = track(make(base), traj, seed=1)
    pred = track(make({**base, 'cleanup': {**base['cleanup'], 'predict_velocity': 1.0}}), traj,
                 seed=1)
    e_plain = np.median(np.abs(plain[20:, :3] - traj[20:, :3]), axis=0)
    e_pred = np.median(np.abs(pred[20:, :3] - traj[20:, :3]), axis=0)
    assert np.all(e_pred < 0.7 * e_plain), (e_plain, e_pred)
    assert e_pred[0] < 0.3 and e_pred[1] < 0.3 and e_pred[2] < np.deg2rad(1.0), e_pred


def test_the_velocity_prediction_shifts_by_the_set_fraction_of_the_velocity() -> None:
    """predict_velocity k: the states move by k x the smoothed change per frame, and that
    shift (what the frame's prior pose adds) is returned; nothing before a velocity exists."""
    rng = np.random.default_rng(2)
    hrn = make({'cleanup': {'predict_velocity': 0.5}})
    hrn.step(event_frame(random_scene(rng), (0.0, 0.0, 0.0, 0.0), rng), 0)
    hrn._velocity = None
    assert hrn._predict_velocity() == {}
    hrn._velocity = {'h': 2.0, 'v': -1.0, 'r': 0.5}
    assert hrn._predict_velocity() == {'h': 1.0, 'v': -0.5, 'r': 0.25}


def test_imu_prediction_moves_the_states_by_the_gyro() -> None:
    """With γ = 0 the cleanup does not move the states, so only the prediction does."""
    rng = np.random.default_rng(0)
    scene = random_scene(rng)
    frame = event_frame(scene, (0, 0, 0, 0), rng)
    hrn = make({'cleanup': {'gamma': 1.0}, 'focal_px': FOCAL})
    for i in range(20):
        e0 = hrn.step(frame, i)
    hrn2 = HRN(paper_config({'cleanup': {'gamma': 0.0},
                                           'focal_px': FOCAL}),
               rng=np.random.default_rng(1))
    hrn2._engine, hrn2._started, hrn2._point = hrn._engine, True, hrn._point
    hrn2.tracker.established = True        # a tracked map (no bootstrap restart of its map)
    hrn2._engine.cfg = hrn2.cfg
    e1 = hrn2.step(frame, 99, gyro_delta=np.array([-0.02, 0.05, 0.1]))
    assert e1.h - e0.h == pytest.approx(FOCAL * 0.05, abs=0.15)
    assert e1.v - e0.v == pytest.approx(FOCAL * 0.02, abs=0.15)
    assert e1.r - e0.r == pytest.approx(0.1, abs=0.01)


def test_imu_fusion_helps_on_fast_motion() -> None:
    """Large inter-frame motion (about 3 px and 3 deg per frame): the gyro keeps the lock."""
    traj = trajectory(240, amp_xy=18.0, amp_roll=0.6, period=40.0)
    base = {'cleanup': {'gamma': 0.5}, 'map': {'learn': False}, 'focal_px': FOCAL}
    plain = track(make(base), traj)
    fused = track(make(base), traj, imu=True)
    e_plain = np.median(np.abs(plain[20:, :3] - traj[20:, :3]), axis=0)
    e_fused = np.median(np.abs(fused[20:, :3] - traj[20:, :3]), axis=0)
    assert e_fused[2] < 0.5 * e_plain[2] and e_fused[0] < e_plain[0], (e_plain, e_fused)
    assert e_fused[2] < np.deg2rad(2.0) and e_fused[0] < 1.0


SQUARE = {'codebook': {'canvas_width': 36, 'canvas_height': 36}}


@pytest.mark.parametrize(('scale', 'ring_weight', 'refine', 'extra'),
                         [(False, 0.0, False, {}), (True, 0.0, False, {}),
                          (False, 1.0, False, {}), (True, 1.0, False, {}),
                          (True, 1.0, True, {}), (False, 0.5, True, {}),
                          (False, 0.0, False, SQUARE),
                          (False, 0.0, False, {'readout': {'source': 'drive'}}),
                          (True, 0.0, False, {'readout': {'source': 'drive'}}),
                          (False, 0.0, False, {'cleanup': {'nonlinearity': 'relu'}})])
def test_fast_path_equals_dense_reference(scale: bool, ring_weight: float, refine: bool,
                                          extra: dict[str, dict[str, object]]) -> None:
    """Same equations, same random draws: readouts agree within 1e-4 relative (32x24).

    Without scale the fast engine runs its direct (θ-spectrum) form; the sixth case is the
    shipped shapes_rotation switches in that form. The last four take the fast engine's
    other branches: h and v cleaned as one 2-D batch (a square canvas), the drive readout
    (no batched cleanup; its bound is the marginal's in both engines), also of the scale
    factor (a codebook that is no complete DFT), and a cleanup other than ``exp`` (one factor
    at a time). (``cleanup.whiten`` has no such test: it gives every
    term weight 1, also the near-zero terms whose phase is the engines' different rounding,
    and the two differ by up to 14 % on these frames.)"""
    base = {'width': 32, 'height': 24,
            'logpolar': {'n_theta': 32, 'n_rho': 16, 'ring_weight': ring_weight},
            'codebook': {'canvas_width': 36, 'canvas_height': 26},
            'map': {'block_iterations': 10}, 'scale': {'enabled': scale},
            'readout': {'refine': refine},
            'tracking': {'overlap_highpass': 1.0,      # (3 bins on 128x96 canvases)
                         'psr_full': 0.0}}   # the dense path has no distinctiveness term
    if refine:      # and the other switches of the shipped configs
        base['codebook'] = {**base['codebook'], 'kernel_sigma': 0.7}   # type: ignore[dict-item]
        base['cleanup'] = {'predict_velocity': 1.0, 'iterations_per_frame': 2}
        base['readout'] = {'refine': True, 'refine_input': 'h,v,z'}   # r refines on its state
    for key, section in extra.items():
        base[key] = {**base.get(key, {}), **section}       # type: ignore[dict-item]
    fast = make(base, seed=3)
    eng = fast._engine
    assert eng._direct is not scale                    # type: ignore[attr-defined]
    assert eng._full == {'h': True, 'v': True, 'r': True,   # type: ignore[attr-defined]
                         **({'z': False} if scale else {})}
    assert eng._hv_rows is (extra is SQUARE)           # type: ignore[attr-defined]
    assert eng._row_batch is (not scale and extra in ({}, SQUARE))  # type: ignore[attr-defined]
    assert eng.m.dtype == np.complex64       # type: ignore[attr-defined]  # either form
    dense = make({**base, 'path': 'dense'}, seed=3)
    rng = np.random.default_rng(0)
    scene = random_scene(rng, size=100, n_shapes=40)
    traj = trajectory(40, amp_xy=3.0, amp_roll=0.3, amp_zoom=0.1, period=40.0)
    updated = 0
    for i, pose in enumerate(traj):
        frame = event_frame(scene, tuple(pose), rng, width=32, height=24)
        a, b = fast.step(frame, i), dense.step(frame, i)
        for k in fast.factors:
            rel = np.abs(a.similarity[k] - b.similarity[k]).max() / np.abs(b.similarity[k]).max()
            assert rel < 1e-4, (i, k, rel)
        np.testing.assert_allclose([a.h, a.v, a.r, a.z], [b.h, b.v, b.r, b.z], rtol=1e-4,
                                   atol=1e-6)
        assert (a.map_updated, a.state) == (b.map_updated, b.state), i
        assert a.quality == pytest.approx(b.quality, abs=1e-4), i
        updated += a.map_updated
    per_frame = fast.cfg.cleanup.iterations_per_frame      # blocked for 10 iterations
    # (the drive's peaks stay below the quality's sharpness floor here: no map update in
    # either engine)
    assert updated == (0 if extra.get('readout') else 40 - 10 // per_frame)
    np.testing.assert_allclose(fast.map_image(), dense.map_image(), atol=1e-6)
    np.testing.assert_allclose(fast.egocentric_map_image(), dense.egocentric_map_image(),
                               atol=1e-6)


def test_fast_codebook_products_equal_the_matrix_products() -> None:
    """``X† a`` and ``X p`` of every factor by FFT (complete DFT codebooks: h, v, r) or by
    products (the scale factor's codebook) equal the codebook matrices' products."""
    eng = make({'scale': {'enabled': True}})._engine
    rng = np.random.default_rng(4)
    for name, X in eng.X.items():
        a = rng.normal(size=X.shape[0]) + 1j * rng.normal(size=X.shape[0])
        p = rng.normal(size=X.shape[1])
        np.testing.assert_allclose(eng.book_decode(name, a), X.conj().T @ a, atol=1e-9)
        np.testing.assert_allclose(eng.book_encode(name, p), X @ p, atol=1e-9)
    assert [k for k, full in eng._full.items() if full] == ['h', 'v', 'r']


def test_map_update_is_eq9_with_the_anchor_of_the_latest_start() -> None:
    """``m ← μ1 m + μ2 m0 + (1 - μ1 - μ2) t`` (Eq. 9) element by element, also after the map
    restarts on another frame (``start``): the anchor is the new first map, not the old one
    (the engine caches μ2 m0 between updates)."""
    eng = make()._engine
    rng = np.random.default_rng(6)
    canvases = [rng.random((eng.g.canvas_height, eng.g.canvas_width)) for _ in range(3)]
    point = {'h': 2.0, 'v': -1.0, 'r': 3.0}
    for first in canvases[:2]:
        eng.start(first, np.random.default_rng(0))
        m0 = np.fft.fft2(first)
        np.testing.assert_allclose(eng.m0, m0, rtol=1e-5, atol=1e-3)
        for mu1, mu2 in ((0.9, 0.05), (0.9, 0.05), (0.8, 0.1)):
            S = eng.encode(canvases[2])
            target = np.asarray(eng.map_target(S, point), np.complex128)
            want = mu1 * np.asarray(eng.m, np.complex128) + mu2 * m0 + (1 - mu1 - mu2) * target
            eng.update_map(S, point, mu1, mu2)
            np.testing.assert_allclose(eng.m, want, rtol=1e-5, atol=1e-3)
            np.testing.assert_array_equal(eng._mc, np.conj(eng.m))   # type: ignore[attr-defined]


def test_dense_path_with_random_codebooks_recovers_a_shift() -> None:
    over = {'width': 32, 'height': 24, 'path': 'dense', 'logpolar': {'n_theta': 32, 'n_rho': 24},
            'codebook': {'kind': 'random', 'dim': 1024}, 'map': {'learn': False},
            'hot_pixel_rate': 0.0}     # 40 views of one pose: every edge would count as hot
    traj = np.array([(0.0, 0.0, 0.0, 0.0)] + [(2.0, -1.5, 0.0, 0.0)] * 40)
    rng = np.random.default_rng(5)
    scene = random_scene(rng, size=100, n_shapes=40)
    hrn = make(over, seed=2)
    for i, pose in enumerate(traj):
        e = hrn.step(event_frame(scene, tuple(pose), rng, width=32, height=24), i)
    assert abs(e.h - 2.0) < 0.7 and abs(e.v + 1.5) < 0.7 and abs(e.r) < 0.1


def test_map_learning_switch_block_and_images() -> None:
    traj = trajectory(30, amp_xy=2.0)
    hrn = make({'map': {'block_iterations': 10}})
    rng = np.random.default_rng(0)
    scene = random_scene(rng)
    flags = [hrn.step(event_frame(scene, tuple(p), rng), i).map_updated
             for i, p in enumerate(traj)]
    assert flags == [False] * 10 + [True] * 20
    assert hrn.map_image().shape == (72, 96) and hrn.egocentric_map_image().shape == (72, 96)
    frozen = make({'map': {'learn': False}})
    m0 = None
    for i, p in enumerate(traj):
        e = frozen.step(event_frame(scene, tuple(p), rng), i)
        m0 = frozen.map_image() if m0 is None else m0
    assert not e.map_updated
    np.testing.assert_array_equal(frozen.map_image(), m0)
    assert set(e.similarity) == {'h', 'v', 'r'} and e.similarity['r'].shape == (96,)
    assert hrn.readout_axis('r').shape == (96,) and set(e.confidence) == {'h', 'v', 'r'}


def test_empty_frames_repeat_the_pose_without_iterating() -> None:
    hrn = make()
    e = hrn.step(np.zeros((72, 96), np.uint8), 5)
    assert not e.valid and e.iteration == 0
    rng = np.random.default_rng(0)
    frame = event_frame(random_scene(rng), (0, 0, 0, 0), rng)
    e1 = hrn.step(frame, 6)
    e2 = hrn.step(np.zeros((72, 96), np.uint8), 7)
    assert e1.valid and not e2.valid and (e2.h, e2.r, e2.iteration) == (e1.h, e1.r, 1)


@pytest.mark.parametrize('path', ['fast', 'dense', 'spiking'])
def test_a_blank_cleanup_input_keeps_the_states(path: str) -> None:
    """A zero input (nothing to unbind) must not shrink the states: zero h and v are a fixed
    point of the resonator, so a shrinking state froze the network for good."""
    over = {'path': 'fast'} if path != 'dense' else {
        'path': 'dense', 'width': 24, 'height': 18, 'logpolar': {'n_theta': 24, 'n_rho': 18}}
    if path == 'spiking':
        hrn = make_backend(paper_config(over), rng=np.random.default_rng(1),
                           backend=BackendConfig('spiking', SpikingConfig()))
    else:
        hrn = make(over)
    rng = np.random.default_rng(0)
    w, h = hrn.cfg.width, hrn.cfg.height
    hrn.step(event_frame(random_scene(rng), (0, 0, 0, 0), rng, width=w, height=h), 0)
    eng = hrn._engine
    before = {k: x.copy() for k, x in eng.state.items()}
    S = eng.encode(np.zeros((hrn.geometry.canvas_height, hrn.geometry.canvas_width)))
    for _ in range(3):
        eng.iterate(S)
    for k, x in eng.state.items():
        np.testing.assert_allclose(x, before[k], atol=1e-12, err_msg=k)
    # and the update still moves a state when the cleanup carries something
    x = np.exp(1j * np.linspace(0, 1, 8))
    cleaned = np.exp(-1j * np.linspace(0, 1, 8))
    np.testing.assert_allclose(blend_state(x, cleaned.copy(), 0.9), 0.1 * x + 0.9 * cleaned)
    two = np.stack([cleaned, np.zeros(8, complex)])
    np.testing.assert_allclose(blend_state(np.stack([x, x]), two, 0.9),
                               np.stack([0.1 * x + 0.9 * cleaned, x]))


def test_noise_frames_above_max_fill_are_skipped() -> None:
    """A still camera fills fixed-count packets with noise: such frames must not become the map."""
    rng = np.random.default_rng(0)
    noise = (rng.random((72, 96)) < 0.45).astype(np.uint8)
    hrn = make()
    e = hrn.step(noise, 0)
    assert not e.valid and e.iteration == 0
    frame = event_frame(random_scene(rng), (0, 0, 0, 0), rng)
    assert hrn.step(frame, 1).valid
    assert make({'max_fill': 1.0}).step(noise, 0).valid


def test_bad_inputs_and_configs() -> None:
    hrn = make()
    with pytest.raises(TrackingError, match=r'expected \(72, 96\)'):
        hrn.step(np.zeros((48, 64)), 0)
    with pytest.raises(TrackingError, match='non-finite'):
        hrn.step(np.full((72, 96), np.nan), 0)
    rng = np.random.default_rng(0)
    frame = event_frame(random_scene(rng), (0, 0, 0, 0), rng)
    hrn.step(frame, 0)
    with pytest.raises(ConfigError, match='focal_px'):
        hrn.step(frame, 1, gyro_delta=np.zeros(3))
    with pytest.raises(ConfigError, match='focal_px'):
        make({'imu': {'enabled': True}})             # refused at construction
    imu_hrn = make({'focal_px': 80.0})
    imu_hrn.step(frame, 0)
    with pytest.raises(TrackingError, match='gyro_delta'):
        imu_hrn.step(frame, 1, gyro_delta=np.zeros(2))
    with pytest.raises(ConfigError, match='path fast needs'):
        ResonatorConfig(codebook=from_dict(type(ResonatorConfig().codebook), {'kind': 'random'}))
    with pytest.raises(ConfigError, match='mu1 \\+ mu2'):
        paper_config({'map': {'mu1': 0.9, 'mu2': 0.2}})
    with pytest.raises(ConfigError, match='nonlinearity'):
        paper_config({'cleanup': {'nonlinearity': 'tanh'}})
    with pytest.raises(ConfigError, match='smaller than'):
        paper_config({'codebook': {'canvas_width': 50}})
    with pytest.raises(ConfigError, match='unknown'):
        paper_config({'map': {'mu3': 0.1}})
    with pytest.raises(ConfigError, match='camera_from_imu'):
        paper_config({'imu': {'camera_from_imu': [1.0, 0.0]}})
    with pytest.raises(ConfigError, match='refine_input'):
        paper_config({'readout': {'refine_input': 'h,x'}})


def test_cleanup_nonlinearities() -> None:
    c = np.array([-1.0, 0.5, 2.0, 1.0])
    np.testing.assert_allclose(cleanup_weights(c, CleanupConfig(nonlinearity='identity')), c)
    np.testing.assert_allclose(cleanup_weights(c, CleanupConfig(nonlinearity='relu')),
                               [0, 0.5, 2, 1])
    np.testing.assert_allclose(cleanup_weights(c, CleanupConfig(nonlinearity='relu_k', k=2)),
                               [0, 0.25, 4, 1])
    e = cleanup_weights(c, CleanupConfig(nonlinearity='exp', beta=2.0))
    np.testing.assert_allclose(e, np.exp(2.0 * (c / 2.0 - 1.0)))
    np.testing.assert_allclose(cleanup_weights(np.full(3, 1e-20), CleanupConfig(), 1.0), 0.0)


def test_refine_finds_fractional_exponents_and_removes_pixel_locking() -> None:
    """The continuous readout of seed^a is a; on sub-pixel motion it beats the population
    vector of the sharpened state, which is pulled towards whole pixels."""
    phases = fhrr.dft_phases(64)
    for a in (3.37, -10.5, 0.02):
        x = fhrr.power(phases, a)
        assert abs(refine_exponent(x, phases, round(a), 1.0) - a) < 1e-3
    traj = np.zeros((120, 4))
    traj[:, 0] = np.linspace(0.0, 6.0, 120)           # 0.05 px per frame: every fraction
    base = {'cleanup': {'beta': 20.0}, 'map': {'learn': False}}
    plain = track(make(base), traj)
    fine = track(make({**base, 'readout': {'refine': True}}), traj)
    e_plain = np.median(np.abs(plain[10:, 0] - traj[10:, 0]))
    e_fine = np.median(np.abs(fine[10:, 0] - traj[10:, 0]))
    assert e_fine < 0.85 * e_plain, (e_plain, e_fine)


def test_imu_gamma_replaces_cleanup_gamma_only_with_the_imu_on() -> None:
    cfg = paper_config({'cleanup': {'gamma': 0.9}, 'imu': {'gamma': 0.3}})
    assert state_gamma(cfg) == 0.9
    on = paper_config({'cleanup': {'gamma': 0.9},
                                     'imu': {'gamma': 0.3, 'enabled': True}})
    assert state_gamma(on) == 0.3
    unset = paper_config({'cleanup': {'gamma': 0.9}, 'imu': {'enabled': True}})
    assert state_gamma(unset) == 0.9


def test_imu_mu1_replaces_the_map_weight_only_with_the_imu_on() -> None:
    cfg = paper_config({'map': {'mu1': 0.97}, 'imu': {'mu1': 0.985}})
    assert map_mu1(cfg) == 0.97
    on = paper_config({'map': {'mu1': 0.97}, 'imu': {'mu1': 0.985, 'enabled': True},
                                     'focal_px': FOCAL})
    assert map_mu1(on) == 0.985
    unset = paper_config({'map': {'mu1': 0.97}, 'imu': {'enabled': True},
                                        'focal_px': FOCAL})
    assert map_mu1(unset) == 0.97
    with pytest.raises(ConfigError, match=r'imu.mu1 \+ map.mu2'):
        paper_config({'map': {'mu2': 0.1}, 'imu': {'mu1': 0.95}})


def test_the_map_learns_with_imu_mu1_while_the_gyro_predicts() -> None:
    """The map after a gyro-tracked run is the one map.mu1 = imu.mu1 gives, not map.mu1's."""
    traj = trajectory(24, amp_xy=2.0)

    def final_map(over: dict, imu: bool) -> np.ndarray:
        hrn = make({'map': {'block_iterations': 4, **over.get('map', {})},
                    'imu': {'enabled': imu, **over.get('imu', {})}, 'focal_px': FOCAL})
        track(hrn, traj, imu=imu)
        return hrn.map_image()

    with_imu_mu1 = final_map({'map': {'mu1': 0.9}, 'imu': {'mu1': 0.6}}, imu=True)
    np.testing.assert_array_equal(with_imu_mu1, final_map({'map': {'mu1': 0.6}}, imu=True))
    assert np.abs(with_imu_mu1 - final_map({'map': {'mu1': 0.9}}, imu=True)).max() > 1e-3
    # without the IMU, imu.mu1 is not used
    np.testing.assert_array_equal(final_map({'map': {'mu1': 0.9}, 'imu': {'mu1': 0.6}}, imu=False),
                                  final_map({'map': {'mu1': 0.9}}, imu=False))


def map_updates(cfg: dict, n: int, imu: bool, *, reset_at: int = -1, t0_ns: int = 0
                ) -> list[bool]:
    """``map_updated`` of n frames of a random scene 5 ms apart (the gyro's increments with the
    IMU on, none on a map's first frame); the network is reset before frame ``reset_at``."""
    hrn = make(cfg)
    traj = trajectory(n, amp_xy=1.0)
    rng = np.random.default_rng(0)
    scene = random_scene(rng)
    updated = []
    for i, pose in enumerate(traj):
        if i == reset_at:
            hrn.reset()
        g = gyro_between(traj[i - 1], pose) if imu and i not in (0, reset_at) else None
        e = hrn.step(event_frame(scene, tuple(pose), rng), t0_ns + i * 5_000_000,
                     gyro_delta=g)
        updated.append(e.map_updated)
    return updated


@pytest.mark.parametrize(('imu', 'imu_block', 'first'), [(False, 4, 5), (True, 4, 2),
                                                          (True, -1, 5), (True, 0, 0)])
def test_imu_block_iterations_replaces_the_map_block_only_with_the_imu_on(
        imu: bool, imu_block: int, first: int) -> None:
    """2 iterations per frame, frame 0 included (it starts the map, then iterates): after frame
    k the map has seen 2 (k + 1) iterations, and the first update comes on the first frame past
    the block in use (map.block_iterations 10 -> frame 5; imu.block_iterations 4 -> frame 2;
    0 -> frame 0; -1: the map's)."""
    cfg = {'map': {'block_iterations': 10}, 'cleanup': {'iterations_per_frame': 2},
           'imu': {'enabled': imu, 'block_iterations': imu_block}, 'focal_px': FOCAL}
    assert map_block(paper_config(cfg)) == (imu_block if imu and imu_block >= 0
                                                           else 10)
    assert map_updates(cfg, 10, imu).index(True) == first


@pytest.mark.parametrize(('imu', 'block_s', 'first'), [(True, 0.0, None), (True, 0.02, 5),
                                                        (True, 0.015, 4), (True, 0.012, 3),
                                                        (False, 0.012, 5)])
def test_imu_block_s_ends_the_map_block_after_that_time(imu: bool, block_s: float,
                                                        first: int | None) -> None:
    """Frames every 5 ms, 2 iterations each; the gyro's block of 100 iterations does not end
    within 10 frames, so with the IMU on the first update comes on the first frame more than
    imu.block_s after the map's frame (0.02 s -> frame 5 at 25 ms; 0.015 s -> frame 4: the
    frame at exactly 15 ms is still blocked; 0: never); without the IMU the map's own block of
    10 iterations ends it (frame 5) and imu.block_s is not used. A new map (reset at frame 10)
    counts from its own frame."""
    cfg = {'map': {'block_iterations': 10}, 'cleanup': {'iterations_per_frame': 2},
           'imu': {'enabled': imu, 'block_iterations': 100, 'block_s': block_s},
           'focal_px': FOCAL}
    assert map_block_ns(paper_config(cfg)) == (round(block_s * 1e9) if imu else 0)
    updated = map_updates(cfg, 20, imu, reset_at=10, t0_ns=1_000_000_000)
    for half in (updated[:10], updated[10:]):
        assert (half.index(True) if True in half else None) == first


def test_kernel_sigma_encodes_each_pixel_as_a_gaussian_blob() -> None:
    """The first map is the encoded first frame: one pixel on gives a Gaussian of that std."""
    hrn = make({'width': 32, 'height': 24, 'logpolar': {'n_theta': 32, 'n_rho': 16},
                'codebook': {'kernel_sigma': 1.5}})
    frame = np.zeros((24, 32), np.uint8)
    frame[10, 20] = 1
    hrn.step(frame, 0)
    img = hrn.map_image()
    assert img.sum() == pytest.approx(1.0, abs=1e-6)    # the fast engine's map is single
    yy, xx = np.mgrid[0:24, 0:32]
    assert np.sum(img * xx) == pytest.approx(20.0, abs=1e-4)
    assert np.sum(img * yy) == pytest.approx(10.0, abs=1e-4)
    assert np.sqrt(np.sum(img * (xx - 20.0) ** 2)) == pytest.approx(1.5, abs=0.01)


@pytest.mark.parametrize('gate', [0.0, 5.0])
@pytest.mark.parametrize('tracking', [True, False])
def test_imu_gate_rejects_a_frame_that_contradicts_the_gyro(gate: float, tracking: bool) -> None:
    """One frame from a far pose (a glitch) while the gyro says 'still': with the gate the
    readout keeps the prediction and the map is not updated (also without the tracking
    layer's own quality gate, and with the gate as the only check: no correction limit);
    without it the readout jumps."""
    rng = np.random.default_rng(4)
    scene = random_scene(rng)
    hrn = make({'map': {'block_iterations': 0},
                'cleanup': {'gamma': 0.9, 'iterations_per_frame': 2},
                'tracking': {'enabled': tracking},
                'focal_px': FOCAL, 'imu': {'gate_deg': gate, 'max_correction_deg_s': 0.0}})
    still = np.zeros(3)
    for i in range(30):
        hrn.step(event_frame(scene, (0.0, 0.0, 0.0, 0.0), rng), i, gyro_delta=still)
    glitch = hrn.step(event_frame(scene, (3.0, -2.0, 0.15, 0.0), rng), 30, gyro_delta=still)
    jumped = max(abs(glitch.h), abs(glitch.v)) > 1.5 or abs(glitch.r) > 0.1
    if gate:
        assert hrn.rejected_frames == 1 and not glitch.map_updated
        assert abs(glitch.h) < 0.5 and abs(glitch.v) < 0.5 and abs(glitch.r) < 0.02
        assert hrn.innovation_deg > gate
    else:
        assert jumped and glitch.map_updated and hrn.rejected_frames == 0
    after = hrn.step(event_frame(scene, (0.0, 0.0, 0.0, 0.0), rng), 31, gyro_delta=still)
    if gate:
        assert abs(after.h) < 0.5 and abs(after.r) < 0.02


def still_with_gyro(imu: dict) -> tuple[HRN, np.ndarray, np.random.Generator, Estimate]:
    """A network with the gyro settings ``imu`` (gate 5°) after 30 frames of a still camera
    10 ms apart with a still gyro: (network, scene, generator, last estimate)."""
    rng = np.random.default_rng(4)
    scene = random_scene(rng)
    hrn = make({'map': {'block_iterations': 0, 'mu1': 0.985, 'mu2': 0.0075},
                'cleanup': {'gamma': 0.9, 'iterations_per_frame': 2},
                'focal_px': FOCAL, 'imu': {'gate_deg': 5.0, **imu}})
    for i in range(30):
        last = hrn.step(event_frame(scene, (0.0, 0.0, 0.0, 0.0), rng), i * 10_000_000,
                        gyro_delta=np.zeros(3))
    return hrn, scene, rng, last


def test_imu_correction_limit_cuts_the_readout_to_the_rate_times_the_frame_interval() -> None:
    """The camera steps 1 px right while the gyro says 'still': with
    ``max_correction_deg_s`` 20 and frames 10 ms apart, each readout moves at most 0.2 deg,
    f tan(0.2 deg) = 0.279 px, from the prediction, so the estimate walks to the new pose in
    such steps; without the limit it jumps in one frame."""
    step = FOCAL * np.tan(np.radians(0.2))
    for limit in (0.0, 20.0):
        hrn, scene, rng, last = still_with_gyro({'max_correction_deg_s': limit})
        assert hrn.limited_frames == 0
        est = [hrn.step(event_frame(scene, (1.0, 0.0, 0.0, 0.0), rng), (30 + i) * 10_000_000,
                        gyro_delta=np.zeros(3)) for i in range(12)]
        hs = [last.h] + [e.h for e in est]
        if limit:
            assert np.diff(hs[:4]) == pytest.approx([step] * 3, abs=0.005)
            assert hrn.limited_frames == 3
            assert all(e.map_updated for e in est[:3])      # a cut readout is no rejection
        else:
            assert hs[1] == pytest.approx(1.0, abs=0.1)
            assert hrn.limited_frames == 0
        assert hs[-1] == pytest.approx(1.0, abs=0.08)


def test_the_correction_limit_grows_with_the_gyros_own_turn() -> None:
    """The gyro reports a 0.0125 rad (0.7162°) pan the camera does not make: the readout pulls
    back towards the still view, cut to max_correction_deg_s x dt + fraction x gyro turn
    (20°/s x 10 ms + 0.5 x 0.7162° = 0.5581°, against 0.2° with fraction 0). The same frames
    and readout in both runs, so the cut moves differ by exactly 0.5581 / 0.2."""
    moves = []
    for fraction in (0.0, 0.5):
        hrn, scene, rng, last = still_with_gyro({'max_correction_deg_s': 20.0,
                                                 'max_correction_fraction': fraction})
        pan = gyro_between(np.zeros(3), np.array([1.0, 0.0, 0.0]))     # 1 px at f = 80
        est = hrn.step(event_frame(scene, (0.0, 0.0, 0.0, 0.0), rng), 300_000_000,
                       gyro_delta=pan)
        assert hrn.limited_frames == 1 and hrn.rejected_frames == 0
        moves.append(est.h - (last.h + 1.0))          # the cut pull-back from the prediction
    turn = np.degrees(0.0125)
    assert moves[1] / moves[0] == pytest.approx((0.2 + 0.5 * turn) / 0.2, rel=2e-3)
