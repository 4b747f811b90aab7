"""The paper's evaluation protocol: known answers on synthetic trajectories, and bad inputs."""

from __future__ import annotations

import numpy as np
import pytest

from hrn_vo_ros.core.evaluation.lag import lag_search
from hrn_vo_ros.core.evaluation.metrics import (
    arm_metrics,
    KIND_METRICS,
    rotation_metrics,
    translation_metrics,
)
from hrn_vo_ros.core.evaluation.protocol import (
    estimate_lag,
    EstimateSeries,
    evaluate,
    lag_scan,
    relative_position_errors,
    umeyama,
)
from hrn_vo_ros.core.evaluation.samples import align_samples, GroundTruthArrays
from hrn_vo_ros.core.evaluation.series import EVAL_KINDS
from hrn_vo_ros.core.events.sequence import Trajectory
from hrn_vo_ros.core.odometry.geometry import (
    euler_ptr_to_matrix,
    matrix_to_euler_ptr,
    matrix_to_quat,
    matrix_to_swing_twist,
    quat_to_matrix,
    rotation_angle,
    so3_exp,
    so3_log,
    swing_twist_to_matrix,
)
from hrn_vo_ros.errors import ConfigError, DatasetError

SECONDS = 20.0


def _signal(t: np.ndarray, amp: float, f: tuple[float, ...], ph: float) -> np.ndarray:
    return amp * sum(np.sin(2 * np.pi * fk * t * (1 + 0.05 * t) + ph * (k + 1))
                     for k, fk in enumerate(f)) / len(f)


def _rotation_gt(world: np.ndarray) -> tuple[Trajectory, np.ndarray]:
    """GT of a pan/tilt/roll motion seen in an arbitrary world frame, and the 200 Hz times."""
    t = np.arange(0.0, SECONDS, 1 / 200)
    R = euler_ptr_to_matrix(_signal(t, 0.35, (0.31, 0.47), 0.3),
                            _signal(t, 0.3, (0.23, 0.61), 1.1),
                            _signal(t, 0.8, (0.19, 0.37), 2.0))
    Rw = world @ R
    return Trajectory((t * 1e9).astype(np.int64), np.zeros((len(t), 3)),
                      matrix_to_quat(Rw)), t


def _relative_angles(gt: Trajectory, t: np.ndarray,
                     convention: str = 'swing-twist') -> tuple[np.ndarray, ...]:
    """Pan/tilt/roll of R_gt(t0)^T R_gt(t) at est times t (exact, from the GT's own motion)."""
    gt_t = gt.t * 1e-9
    R = quat_to_matrix(gt.quat)
    # geodesic interpolation as the protocol does, then relative to the first estimate time
    i = np.clip(np.searchsorted(gt_t, t, side='right') - 1, 0, len(gt_t) - 2)
    a = (t - gt_t[i]) / (gt_t[i + 1] - gt_t[i])
    Ri = R[i] @ so3_exp(so3_log(np.swapaxes(R[i], 1, 2) @ R[i + 1]) * a[:, None])
    to_angles = matrix_to_euler_ptr if convention == 'euler' else matrix_to_swing_twist
    pan, tilt, roll = to_angles(np.swapaxes(Ri[:1], 1, 2) @ Ri)
    return pan, tilt, np.unwrap(roll)


WORLD = euler_ptr_to_matrix(0.4, -0.7, 2.5)
SIM = 60.0 * np.array([[np.cos(0.5), -np.sin(0.5)], [np.sin(0.5), np.cos(0.5)]]) @ np.diag(
    [1.0, -1.0])


def _rotation_case(lag: float = 0.0, roll_sign: float = 1.0, noise: float = 0.0,
                   seed: int = 0, convention: str = 'swing-twist'
                   ) -> tuple[Trajectory, EstimateSeries]:
    gt, _ = _rotation_gt(WORLD)
    t = np.arange(0.013, SECONDS - 0.02, 1 / 160)
    pan, tilt, roll = _relative_angles(gt, t, convention)
    hv = (SIM @ np.stack([pan, tilt])).T + np.array([4.0, -9.0])
    rng = np.random.default_rng(seed)
    hv += rng.normal(0, noise, hv.shape)
    est = EstimateSeries(((t + lag) * 1e9).astype(np.int64), hv[:, 0], hv[:, 1],
                         roll_sign * roll + 0.2)
    return gt, est


def test_perfect_rotation_estimate_has_no_error() -> None:
    gt, est = _rotation_case()
    res = evaluate(gt, est, 'rotation')
    assert res.metrics['median_angle_deg'] < 0.01
    assert abs(res.lag_s) < 2e-3
    assert res.roll_corr > 0.999
    assert res.warnings == ()


@pytest.mark.parametrize('convention, other', [('swing-twist', 'euler'),
                                               ('euler', 'swing-twist')])
def test_rotation_convention_is_the_one_asked_for(convention: str, other: str) -> None:
    """A perfect estimate in one convention is exact there; read in the other, its roll misses
    the twist of about pan * tilt / 2 (pan, tilt up to ~0.35 rad here: up to ~3 deg)."""
    gt, est = _rotation_case(convention=convention)
    res = evaluate(gt, est, 'rotation', convention=convention)
    assert res.metrics['median_angle_deg'] < 0.01
    assert res.calibration['convention'] == convention
    wrong = evaluate(gt, est, 'rotation', convention=other)
    assert 0.2 < wrong.metrics['median_angle_deg'] < 3.0
    assert wrong.metrics['median_roll_deg'] > 0.2


def test_known_similarity_is_recovered() -> None:
    gt, est = _rotation_case()
    res = evaluate(gt, est, 'rotation', calib='full')
    cal = res.calibration
    assert cal['reflected'] is True
    assert cal['scale'] == pytest.approx(1 / 60.0, rel=1e-3)
    assert res.calibration['roll_offset_rad'] == pytest.approx(0.2, abs=1e-3)
    assert res.metrics['median_angle_deg'] < 0.01


def test_calibration_on_flagged_estimates_ignores_a_held_stretch() -> None:
    """An output held still over the first half of the calibration segment (a lost track)
    pulls the protocol's fitted scale off 1/60 and every later error up; fitted on the other
    estimates only (``calib_use``), the calibration is exact again and so are the errors."""
    gt, est = _rotation_case()
    cal = evaluate(gt, est, 'rotation').series.calib
    idx = np.flatnonzero(cal)
    held = np.zeros(len(est), bool)
    held[idx[0]:idx[len(idx) // 2]] = True
    h, v = est.h.copy(), est.v.copy()
    h[held], v[held] = h[idx[0]], v[idx[0]]
    est = EstimateSeries(est.t, h, v, est.r)
    lag = 0.0
    plain = evaluate(gt, est, 'rotation', lag_s=lag)
    assert abs(plain.calibration['scale'] * 60.0 - 1.0) > 0.05
    assert plain.metrics['median_angle_deg'] > 0.5
    fixed = evaluate(gt, est, 'rotation', lag_s=lag, calib_use=~held)
    assert fixed.calibration['scale'] == pytest.approx(1 / 60.0, rel=1e-3)
    assert fixed.metrics['median_angle_deg'] < 0.01
    assert 'flagged' in str(fixed.calibration['segment'])
    assert np.array_equal(fixed.series.calib, cal & ~held)


def test_calibration_flags_are_checked() -> None:
    gt, est = _rotation_case()
    with pytest.raises(DatasetError, match='one boolean per estimate'):
        evaluate(gt, est, 'rotation', calib_use=np.ones(len(est) - 1, bool))
    with pytest.raises(DatasetError, match='one boolean per estimate'):
        evaluate(gt, est, 'rotation', calib_use=np.ones(len(est)))
    few = np.zeros(len(est), bool)
    few[np.flatnonzero(evaluate(gt, est, 'rotation').series.calib)[:19]] = True
    with pytest.raises(DatasetError, match='holds 19 flagged estimates'):
        evaluate(gt, est, 'rotation', calib_use=few)


def test_lag_is_found_and_removed() -> None:
    gt, est = _rotation_case(lag=0.12)
    res = evaluate(gt, est, 'rotation')
    assert res.lag_s == pytest.approx(0.12, abs=2e-3)
    assert res.metrics['median_angle_deg'] < 0.05
    res_fixed = evaluate(gt, est, 'rotation', lag_s=0.0)
    assert res_fixed.metrics['median_angle_deg'] > 1.0


def test_lag_from_the_training_part_ignores_a_late_roll_jump() -> None:
    """A roll that jumps by 170 degrees late in the evaluated part (a wrong re-localisation)
    weighs in the whole-run search (the protocol): its lag is 6 ms off the true 0.12 s, and
    the evaluated samples before the jump read about 1 degree off. Searched before the
    evaluated part only, the lag is exact and those samples are too."""
    gt, est = _rotation_case(lag=0.12)
    r = est.r + np.radians(170.0) * (est.t * 1e-9 > 0.9 * SECONDS)
    jumped = EstimateSeries(est.t, est.h, est.v, r)
    run = evaluate(gt, jumped, 'rotation')
    assert abs(run.lag_s - 0.12) > 4e-3
    assert run.metrics['median_angle_deg'] > 0.5
    trained = evaluate(gt, jumped, 'rotation', lag_window='training')
    assert trained.lag_s == pytest.approx(0.12, abs=1e-3)
    assert trained.metrics['median_angle_deg'] < 0.05
    # without a jump both windows find the same lag; an unknown window is refused
    assert evaluate(gt, est, 'rotation', lag_window='training').lag_s == pytest.approx(
        evaluate(gt, est, 'rotation').lag_s, abs=1e-3)
    with pytest.raises(ConfigError, match="lag_window = 'test'"):
        evaluate(gt, est, 'rotation', lag_window='test')


def test_arm_lag_from_the_first_arc() -> None:
    """For the arm the part before the evaluated one is the first arc (up to 5 s): a roll
    jump at 6 s (inside the 70 % training part, after the arc) moves the whole-run lag by
    80 ms and not the first arc's."""
    gt, est = _arm_case()
    r = est.r + np.radians(60.0) * (est.t * 1e-9 > 6.0)
    jumped = EstimateSeries(est.t, est.h, est.v, r)
    assert abs(evaluate(gt, jumped, 'arm').lag_s) > 0.05
    assert evaluate(gt, jumped, 'arm', lag_window='training').lag_s == pytest.approx(
        0.0, abs=1e-3)


def test_wrong_roll_sign_is_detected() -> None:
    gt, est = _rotation_case(roll_sign=-1.0)
    res = evaluate(gt, est, 'rotation')
    assert res.roll_corr < -0.9
    assert any('flipped' in w for w in res.warnings)
    assert res.metrics['median_angle_deg'] > 10.0


def test_noise_gives_proportionate_error() -> None:
    gt, est = _rotation_case(noise=60.0 * np.radians(1.0))  # 1 degree of pan/tilt noise
    res = evaluate(gt, est, 'rotation')
    assert 0.6 < res.metrics['median_angle_deg'] < 1.6


def test_estimate_lag_direct() -> None:
    t = np.arange(0, 10, 0.005)
    sig = np.sin(2 * np.pi * 0.7 * t) + 0.5 * np.sin(2 * np.pi * 1.9 * t)
    lag, corr = estimate_lag(t + 0.07, sig, t, sig)
    assert lag == pytest.approx(0.07, abs=1e-3)
    assert corr > 0.99


def _translation_case(with_z: bool = True) -> tuple[Trajectory, EstimateSeries]:
    t = np.arange(0.0, SECONDS, 1 / 200)
    pos = np.stack([_signal(t, 0.3, (0.21, 0.43), 0.1), _signal(t, 0.2, (0.17, 0.52), 0.9),
                    _signal(t, 0.15, (0.11, 0.29), 1.7)], axis=1)
    roll = _signal(t, 0.12, (0.2, 0.33), 0.4)
    R = euler_ptr_to_matrix(0.0, 0.0, roll)
    gt = Trajectory((t * 1e9).astype(np.int64), pos, matrix_to_quat(R))
    te = np.arange(0.011, SECONDS - 0.02, 1 / 170)
    p = np.stack([np.interp(te, t, pos[:, k]) for k in range(3)], axis=1)
    q = p - p[0] + 0.0  # world = first camera frame here (R(0) = I)
    d0 = 0.8
    hv = (SIM @ q[:, :2].T).T / 0.004
    z = np.log(d0 / (d0 - q[:, 2]))
    r = np.interp(te, t, roll)
    est = EstimateSeries((te * 1e9).astype(np.int64), hv[:, 0], hv[:, 1], r,
                         z if with_z else None)
    return gt, est


def test_perfect_translation_estimate() -> None:
    gt, est = _translation_case()
    res = evaluate(gt, est, 'translation')
    assert res.metrics['median_pos_m'] < 1e-3
    assert res.metrics['rel_pos_pct'] < 0.1
    assert res.calibration['depth_k'] == pytest.approx(-1.0, abs=0.1)


def test_translation_without_scale_column_is_worse_and_says_so() -> None:
    gt, est = _translation_case(with_z=False)
    res = evaluate(gt, est, 'translation')
    assert res.metrics['median_pos_m'] > 0.01
    assert any('no scale column' in w for w in res.warnings)


def _arm_case(pos_lag: float = 0.0) -> tuple[Trajectory, EstimateSeries]:
    """An arm sweep; the estimate's position lags its roll by ``pos_lag`` seconds."""
    t = np.arange(0.0, SECONDS, 1 / 200)
    phi = -0.4 + 0.8 * 0.5 * (1 - np.cos(2 * np.pi * np.clip(t - 0.5, 0, None) / 4.5))
    pos = np.stack([0.45 * np.cos(phi), 0.45 * np.sin(phi), np.full_like(t, 0.4)], axis=1)
    R = np.einsum('nij,jk->nik', euler_ptr_to_matrix(0.0, 0.0, 0.0) @ so3_exp(
        np.stack([np.zeros_like(phi), np.zeros_like(phi), phi], axis=1)), np.diag([1., -1, -1]))
    gt = Trajectory((t * 1e9).astype(np.int64), pos, matrix_to_quat(R))
    te = np.arange(0.02, SECONDS - 0.02, 1 / 120)
    p = np.stack([np.interp(te - pos_lag, t, pos[:, k]) for k in range(3)], axis=1)
    R0 = R[0]
    q = (p - p[0]) @ R0  # first camera frame
    hv = q[:, :2] / 0.01 + 3.0
    ph = np.interp(te, t, phi)
    est = EstimateSeries((te * 1e9).astype(np.int64), hv[:, 0], hv[:, 1], -(ph - ph[0]))
    return gt, est


def test_arm_calibrates_on_first_arc() -> None:
    gt, est = _arm_case()
    res = evaluate(gt, est, 'arm')
    assert res.metrics['median_pos_m'] < 1e-3
    assert res.metrics['median_roll_deg'] < 0.05
    assert res.series.calib.any() and not (res.series.calib & res.series.test).any()


def test_lag_scan_finds_a_position_that_lags_the_roll() -> None:
    gt, est = _arm_case(pos_lag=0.006)
    offsets = np.arange(-10, 11) * 1e-3
    base, curves = lag_scan(gt, est, 'arm', offsets)
    assert abs(base) < 1e-3                      # the protocol aligns by the (unlagged) roll
    pos = np.asarray(curves['median_pos_m'])
    assert offsets[np.argmin(pos)] == pytest.approx(0.006, abs=1.1e-3)
    assert pos.min() < 0.2 * pos[10]             # offset 0 = the protocol's error
    assert np.argmin(curves['median_roll_deg']) == pytest.approx(10, abs=1)
    with pytest.raises(ConfigError, match='finite offset'):
        lag_scan(gt, est, 'arm', np.array([np.nan]))


def test_roll_zero_window_is_a_diagnostic_of_the_start() -> None:
    """A roll off by 0.5 deg only in the first 0.1 s shifts every later roll error under the
    protocol; a longer zeroing window (the diagnostic) sees through it."""
    gt, est = _arm_case()
    t = est.t * 1e-9
    early = t <= t[0] + 0.1
    assert 2 <= int(early.sum()) < 0.05 * len(t)
    r = est.r + np.where(early, np.deg2rad(0.5), 0.0)
    est = EstimateSeries(est.t, est.h, est.v, r)
    protocol = evaluate(gt, est, 'arm')
    assert protocol.metrics['median_roll_deg'] == pytest.approx(0.5, abs=0.05)
    longer = evaluate(gt, est, 'arm', roll_zero_s=2.0)
    assert longer.metrics['median_roll_deg'] < 0.05
    assert longer.calibration['roll_zero_s'] == 2.0
    with pytest.raises(ConfigError, match='roll zeroing window'):
        evaluate(gt, est, 'arm', roll_zero_s=0.0)


def test_umeyama_recovers_similarity_and_guards_reflection() -> None:
    rng = np.random.default_rng(3)
    src = rng.normal(size=(50, 3))
    R = so3_exp(np.array([0.3, -0.2, 1.1]))
    dst = 2.5 * src @ R.T + np.array([1.0, -2.0, 0.5])
    s, Rf, tf = umeyama(src, dst)
    assert s == pytest.approx(2.5)
    np.testing.assert_allclose(Rf, R, atol=1e-9)
    np.testing.assert_allclose(tf, [1.0, -2.0, 0.5], atol=1e-9)
    mirrored = dst * np.array([1.0, 1.0, -1.0])
    _, Rg, _ = umeyama(src, mirrored)
    assert np.linalg.det(Rg) > 0
    _, Rm, _ = umeyama(src, mirrored, allow_reflection=True)
    assert np.linalg.det(Rm) < 0


def test_relative_errors_zero_for_identical_and_scale_with_drift() -> None:
    t = np.linspace(0, 10, 2001)
    p = np.stack([np.sin(t), np.cos(0.7 * t), 0.1 * t], axis=1)
    R = np.repeat(np.eye(3)[None], len(t), axis=0)
    errs = relative_position_errors(p, R, p, R, (1.0, 2.0))
    assert all(np.max(e) < 1e-9 for e in errs.values())
    drift = p + np.stack([0.01 * t, 0 * t, 0 * t], axis=1)
    errs = relative_position_errors(p, R, drift, R, (2.0,))
    assert 0.0 < float(np.median(errs[2.0])) < 5.0


def test_geometry_roundtrips() -> None:
    rng = np.random.default_rng(1)
    pan, tilt, roll = rng.uniform(-1.2, 1.2, (3, 100))
    R = euler_ptr_to_matrix(pan, tilt, roll)
    back = matrix_to_euler_ptr(R)
    np.testing.assert_allclose(np.stack(back), np.stack([pan, tilt, roll]), atol=1e-9)
    q = matrix_to_quat(R)
    np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-9)
    # swing-twist: round trip, the swing keeps the optical axis' own twist at zero, and an Euler
    # pan-then-tilt carries a twist of about -pan * tilt / 2
    Rs = swing_twist_to_matrix(pan, tilt, roll)
    np.testing.assert_allclose(np.stack(matrix_to_swing_twist(Rs)), np.stack([pan, tilt, roll]),
                               atol=1e-9)
    np.testing.assert_allclose(Rs[:, :, 2], swing_twist_to_matrix(pan, tilt, 0.0)[:, :, 2],
                               atol=1e-12)
    _, _, twist = matrix_to_swing_twist(euler_ptr_to_matrix(0.1, 0.08, 0.0))
    assert twist == pytest.approx(-0.1 * 0.08 / 2, rel=0.02)
    assert np.max(rotation_angle(np.swapaxes(R, 1, 2) @ R)) < 1e-7


@pytest.mark.parametrize('mutate, message', [
    (lambda e: EstimateSeries(e.t[:10], e.h[:10], e.v[:10], e.r[:10]), 'only 10 estimates'),
    (lambda e: EstimateSeries(e.t, e.h, e.v[:-1], e.r), "column 'v'"),
    (lambda e: EstimateSeries(e.t[::-1].copy(), e.h, e.v, e.r), 'not strictly increasing'),
    (lambda e: EstimateSeries(e.t + 100_000_000_000, e.h, e.v, e.r), 'no time overlap'),
    (lambda e: EstimateSeries(e.t, e.h * np.nan, e.v, e.r), 'NaN'),
    (lambda e: EstimateSeries(e.t[-700:], e.h[-700:], e.v[-700:], e.r[-700:]),
     'calibration segment'),
])
def test_bad_inputs_raise_clear_errors(mutate: object, message: str) -> None:
    gt, est = _rotation_case()
    bad = mutate(est)  # type: ignore[operator]
    with pytest.raises(DatasetError, match=message):
        evaluate(gt, bad, 'rotation')


def test_unknown_kind_and_calib() -> None:
    gt, est = _rotation_case()
    with pytest.raises(ConfigError, match='unknown evaluation kind'):
        evaluate(gt, est, 'spin')
    with pytest.raises(ConfigError, match='calibration mode'):
        evaluate(gt, est, 'rotation', calib='all')
    with pytest.raises(ConfigError, match='rotation convention'):
        evaluate(gt, est, 'rotation', convention='zyx')


@pytest.mark.parametrize('kind', EVAL_KINDS)
def test_evaluate_dispatches_to_the_kind_metric_function(kind: str) -> None:
    """``evaluate`` reports exactly what the kind's metric function computes on the aligned
    samples (the per-kind API is usable on its own)."""
    case = {'rotation': _rotation_case, 'translation': _translation_case, 'arm': _arm_case}
    gt, est = case[kind]()
    res = evaluate(gt, est, kind)
    assert KIND_METRICS[kind] is {'rotation': rotation_metrics,
                                  'translation': translation_metrics, 'arm': arm_metrics}[kind]
    g = GroundTruthArrays.from_trajectory(gt, 'swing-twist')
    t = est.t.astype(np.float64) * 1e-9 - res.lag_s
    inside = (t >= g.t[0]) & (t <= g.t[-1])
    samples = align_samples(g, t[inside], est, inside, convention='swing-twist',
                            roll_zero_s=0.1)
    direct = KIND_METRICS[kind](samples, res.series.calib, res.series.test)
    assert direct.metrics == res.metrics
    np.testing.assert_array_equal(direct.err, res.series.err)


def test_umeyama_scale_keeps_the_reflection_sign() -> None:
    """A mirrored target without reflections allowed: the scale is tr(DS)/var (Eq. 42), the
    least-squares scale of the best proper rotation (found here by brute force)."""
    from hrn_vo_ros.core.evaluation.alignment import umeyama

    rng = np.random.default_rng(4)
    src = rng.normal(size=(50, 2)) * [3.0, 1.0]
    dst = (src * [1.0, -1.0]) * 2.5
    s, R, _ = umeyama(src, dst, allow_reflection=False)
    xc, yc = src - src.mean(0), dst - dst.mean(0)
    best = (np.inf, 0.0)
    for a in np.linspace(-np.pi, np.pi, 200_001):
        c, sn = np.cos(a), np.sin(a)
        r = xc @ np.array([[c, -sn], [sn, c]]).T
        scale = float(np.sum(r * yc) / np.sum(xc * xc))
        err = float(np.sum((yc - scale * r) ** 2))
        best = min(best, (err, scale))
    assert np.linalg.det(R) > 0
    assert s == pytest.approx(abs(best[1]), rel=1e-3)  # -s with R(a + pi) is the same fit
    assert s < 2.4  # the scale of the mirrored fit would be 2.5


def test_motion_between_frames_of_a_known_trajectory() -> None:
    """A camera that turns about its optical axis at 100°/s and moves along x at 0.5 m/s,
    ground truth every 4 ms from 1 s (the first pose not at 0): times 10, 10, 30 and 10.5 ms
    apart turn 1, 1, 3 and 1.05° and travel 0.5, 0.5, 1.5 and 0.525 cm, between ground-truth
    samples too; the 95th percentile of [1, 1, 1.05, 3] is 1.05 + 0.85 x 1.95; a time past
    the ground truth's end counts as its last pose; one time gives NaN."""
    from hrn_vo_ros.core.evaluation.samples import motion_between
    tg = 1_000_000_000 + np.arange(0, 251) * 4_000_000          # 1 s .. 2 s
    ang = np.radians(100.0) * (tg - tg[0]) * 1e-9
    quat = np.stack([0 * ang, 0 * ang, np.sin(ang / 2), np.cos(ang / 2)], axis=1)
    pos = np.stack([0.5 * (tg - tg[0]) * 1e-9, 0 * ang, 0 * ang], axis=1)
    gt = Trajectory(tg.astype(np.int64), pos, quat)
    ms = np.array([0.0, 10.0, 20.0, 50.0, 60.5])
    tf = (tg[0] + ms * 1e6).astype(np.int64)
    deg, m = motion_between(gt, tf)
    assert deg == pytest.approx(1.05 + 0.85 * 1.95, abs=1e-9)
    assert m == pytest.approx(0.01 * (1.05 + 0.85 * 1.95) / 2.0, abs=1e-12)
    assert motion_between(gt, tf, q=50.0)[0] == pytest.approx(1.025, abs=1e-9)
    late = np.array([tg[-1] - 10_000_000, tg[-1] + 500_000_000], np.int64)
    assert motion_between(gt, late)[0] == pytest.approx(1.0, abs=1e-9)
    assert all(np.isnan(x) for x in motion_between(gt, tf[:1]))


def test_umeyama_refuses_too_few_or_mismatched_points() -> None:
    """d + 1 points are enough in d dimensions (a triangle in the plane); d are not, nor a
    target of another shape."""
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0]])
    s, R, t = umeyama(tri, 3.0 * tri + [1.0, -1.0])
    assert s == pytest.approx(3.0) and np.allclose(R, np.eye(2)) and np.allclose(t, [1.0, -1.0])
    with pytest.raises(DatasetError, match='at least 3 matching points'):
        umeyama(tri[:2], tri[:2])
    with pytest.raises(DatasetError, match='at least 3 matching points'):
        umeyama(tri, tri[:, :1])


def test_the_lag_search_needs_an_overlap_of_four_max_lags_and_skips_constant_signals() -> None:
    """The overlap runs from the later start to the earlier end: 2 s + one grid step is
    enough for a 0.5 s lag search, less is refused; a constant signal pair correlates 0."""
    t_gt = np.linspace(0.0, 10.0, 4001)
    gt = [np.sin(2.0 * t_gt), np.ones_like(t_gt)]
    for start, ok in ((8.0 - 1.0 / 400.0, True), (8.01, False)):
        t_est = np.linspace(start, 10.0, 801)
        est = [np.sin(2.0 * t_est), np.ones_like(t_est)]
        if ok:
            lag, corrs = lag_search(t_est, est, t_gt, gt, rate_hz=400.0, max_lag_s=0.5,
                                    squared=True)
            assert lag == pytest.approx(0.0, abs=1e-6)
            assert corrs[0] == pytest.approx(1.0) and corrs[1] == 0.0
        else:
            with pytest.raises(DatasetError, match='overlap for 1.99 s only'):
                lag_search(t_est, est, t_gt, gt, rate_hz=400.0, max_lag_s=0.5, squared=True)


def test_relative_errors_by_hand() -> None:
    """Ground truth along x at 0, 1, 1.5, 2.9 and 4 m, sub-trajectories of L = 2 m: only the
    pair (1 m, 2.9 m) ends within 0.2 L of d + L (from 0 the nearest end is 1.5 m, 0.5 m off;
    from 1.5 m it is 4 m, 0.5 m off; from 2.9 m, 4 m is 0.9 m off). An estimate turned by 60°
    there errs by the chord 2 sin 30° x 1.9 m = 1.9 m, 95 % of L; one stretched by 10 %, 9.5 %."""
    x = np.array([0.0, 1.0, 1.5, 2.9, 4.0])
    p = np.stack([x, 0 * x, 0 * x], axis=1)
    eye = np.repeat(np.eye(3)[None], len(x), axis=0)
    c, s = np.cos(np.pi / 3), np.sin(np.pi / 3)
    turned = np.repeat(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])[None], len(x), 0)
    assert relative_position_errors(p, eye, p, turned, (2.0,))[2.0] == pytest.approx([95.0])
    assert relative_position_errors(p, eye, 1.1 * p, eye, (2.0,))[2.0] == pytest.approx([9.5])
    # L = 2.5 m on 0, 1, 3, 3.5 m: from 0 the end 3 m is exactly 0.2 L off (kept); from 1 m
    # the last pose, 3.5 m, is exact; stretched by 10 %: 0.1 x 3 / 2.5 and 0.1 x 2.5 / 2.5
    x = np.array([0.0, 1.0, 3.0, 3.5])
    p = np.stack([x, 0 * x, 0 * x], axis=1)
    eye = eye[:4]
    assert relative_position_errors(p, eye, 1.1 * p, eye, (2.5,))[2.5] == pytest.approx(
        [12.0, 10.0])


def test_per_axis_rotation_errors_in_degrees() -> None:
    """An estimate exact until 75 % of the run, then 0.6 px off in h and 0.003 rad off in
    roll: h maps to (pan, tilt) by diag(1, -1) Rot(-0.5) / 60 (SIM), so pan is off by
    0.01 cos 0.5 rad = 0.5028°, tilt by 0.01 sin 0.5 rad = 0.2747°, roll by 0.1719°; the
    plotted series are in degrees."""
    gt, est = _rotation_case()
    late = est.t * 1e-9 > 0.75 * SECONDS
    off = EstimateSeries(est.t, est.h + 0.6 * late, est.v, est.r + 0.003 * late)
    res = evaluate(gt, off, 'rotation')
    assert res.metrics['median_pan_deg'] == pytest.approx(0.5028, abs=0.002)
    assert res.metrics['median_tilt_deg'] == pytest.approx(0.2747, abs=0.002)
    assert res.metrics['median_roll_deg'] == pytest.approx(0.1719, abs=0.002)
    ref = evaluate(gt, est, 'rotation')
    pan, _, _ = _relative_angles(gt, est.t * 1e-9)
    i = len(pan) // 2
    assert ref.series.gt[:, 0] == pytest.approx(np.degrees(
        np.interp(ref.series.t_s, est.t * 1e-9 - gt.t[0] * 1e-9, pan)), abs=0.01)
    assert ref.series.est[i, 0] == pytest.approx(ref.series.gt[i, 0], abs=0.01)
