"""The graph's Odometry follows its estimates: a simulated translation through real processes.

``hrn-vo demo --kind translation`` (bag player → packetizer → resonator → recorder over DDS)
records ``/resonator_node/odom`` next to the raw readouts. The Odometry positions must move and
be the translation model of the readouts, so that after the evaluation protocol's calibration
(core/evaluation) their errors against the ground truth are the ones of ``est.csv``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray
import pytest

from hrn_vo_ros.cli.graph import ODOM_TOPIC
from hrn_vo_ros.cli.main import main as hrn_vo
from hrn_vo_ros.core.evaluation.protocol import evaluate
from hrn_vo_ros.core.evaluation.series import EstimateSeries
from hrn_vo_ros.core.odometry.odometry import matrix_from_quat, R_BASE_OPTICAL
from hrn_vo_ros.io.bags import iter_messages, open_bag, typestore
from hrn_vo_ros.io.ecd import read_calib, read_groundtruth
from hrn_vo_ros.io.estimates import read_estimates
from hrn_vo_ros.io.yamlconfig import load_sections

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / 'config' / 'shapes_translation.yaml'
pytestmark = pytest.mark.ros


def read_odometry(bag: Path) -> tuple[NDArray[np.int64], NDArray[np.float64],
                                      NDArray[np.float64], list[str]]:
    """Stamps, positions (n, 3), quaternions xyzw (n, 4) and child frames of the odometry."""
    reader, ts = open_bag(bag), typestore()
    rows = []
    try:
        for m in iter_messages(reader, [ODOM_TOPIC]):
            msg = ts.deserialize_cdr(m.raw, m.msgtype)
            p, q = msg.pose.pose.position, msg.pose.pose.orientation
            rows.append((msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec,
                         (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), msg.child_frame_id))
    finally:
        reader.close()
    rows.sort(key=lambda r: r[0])
    return (np.array([r[0] for r in rows], np.int64), np.array([r[1] for r in rows]),
            np.array([r[2] for r in rows]), [r[3] for r in rows])


@pytest.mark.slow  # ~25 s on a quiet 2-core machine (6 s simulated, 1000-event frames)
def test_graph_odometry_follows_the_estimates(tmp_path: Path) -> None:
    out = tmp_path / 'demo'
    assert hrn_vo(['demo', '--kind', 'translation', '--seconds', '6', '--seed', '1',
                   '--rate', '0', '--out', str(out), '--timeout', '300']) == 0
    est = read_estimates(out / 'est.csv')
    assert est.z is not None
    t, pos, quat, child = read_odometry(out / 'graph_bag')
    np.testing.assert_array_equal(t, est.t)              # one Odometry per estimate, same stamp
    assert set(child) == {'base_link'}
    assert np.ptp(pos, axis=0).max() > 0.01, 'the odometry does not move'
    # back to the optical frame of the first camera pose (mount all zero in the config)
    B = R_BASE_OPTICAL
    p_opt = pos @ B
    R_opt = np.array([B.T @ matrix_from_quat(q) @ B for q in quat])
    sections = load_sections(CONFIG)
    d = float(sections['resonator_node']['odometry']['depth_m'])
    # what the demo sets odometry.focal_length_px to: fx / downsample
    f = read_calib(out / 'sequence').fx / float(sections['packetizer_node']['downsample'])
    # the translation model on every frame: x = h d / f, y = v d / f, z = d (1 - e^-z), R_z(r)
    np.testing.assert_allclose(p_opt[:, 0], est.h * d / f, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(p_opt[:, 1], est.v * d / f, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(p_opt[:, 2], d * -np.expm1(-est.z), rtol=1e-9, atol=1e-15)
    roll = np.arctan2(R_opt[:, 1, 0], R_opt[:, 0, 0])
    np.testing.assert_allclose(roll, est.r, rtol=0, atol=1e-12)
    np.testing.assert_allclose(R_opt[:, 2, 2], 1.0, rtol=0, atol=1e-12)  # about z only
    # the protocol on the odometry positions (its calibration absorbs d / f) gives est.csv's
    # errors
    gt = read_groundtruth(out / 'sequence')
    ref = evaluate(gt, est, 'translation')
    got = evaluate(gt, EstimateSeries(t=t, h=p_opt[:, 0], v=p_opt[:, 1], r=roll,
                                      z=-np.log1p(-p_opt[:, 2] / d)), 'translation')
    assert ref.metrics.keys() == got.metrics.keys()
    for key, value in ref.metrics.items():
        assert got.metrics[key] == pytest.approx(value, rel=1e-9, abs=1e-12), key
    assert 0.0 < ref.metrics['median_pos_m'] < 0.05
    figures = (f'median_pos_m est.csv {ref.metrics["median_pos_m"]:.6f} odometry '
               f'{got.metrics["median_pos_m"]:.6f}; rel_pos_pct {ref.metrics["rel_pos_pct"]:.3f} '
               f'/ {got.metrics["rel_pos_pct"]:.3f}; span {np.ptp(pos, axis=0).round(3)} m')
    print(figures)  # noqa: T201 - the measured figures, shown with -s
