"""The odometry pipeline (core/pipeline.py): frames of a known motion in, that motion out."""

from __future__ import annotations

from typing import Any

from hrn_synth import event_frame, random_scene
import numpy as np
from numpy.typing import NDArray
import pytest

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.evaluation.baseline import config_like, PhaseCorrelationBaseline
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.frames import Packetizer
from hrn_vo_ros.core.events.packet_config import PacketizerConfig
from hrn_vo_ros.core.events.sequence import ImuData
from hrn_vo_ros.core.hrn.backends import make_backend
from hrn_vo_ros.core.hrn.config import ResonatorConfig
from hrn_vo_ros.core.odometry.estimate import Estimate
from hrn_vo_ros.core.odometry.imu import GyroIntegrator
from hrn_vo_ros.core.pipeline import OdometryPipeline
from hrn_vo_ros.errors import ConfigError

POSE = (4.0, 2.0, 0.2)
DT = 5_000_000


def frames(n: int = 40, seed: int = 0) -> list[NDArray[np.uint8]]:
    """The first frame at pose 0, then views at :data:`POSE`."""
    rng = np.random.default_rng(seed)
    scene = random_scene(rng)
    return [event_frame(scene, (0.0, 0.0, 0.0, 0.0) if i == 0 else (*POSE, 0.0), rng)
            for i in range(n)]


class Recorder:
    """An estimator that returns the frame's pixel count as ``h`` and keeps its inputs."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, NDArray[Any], NDArray[Any] | None]] = []

    def step(self, image: NDArray[Any], t_ns: int, *,
             gyro_delta: NDArray[Any] | None = None) -> Estimate:
        self.calls.append((t_ns, image, gyro_delta))
        return Estimate(t_ns=t_ns, h=float(image.sum()), v=-1.0, r=0.5, z=0.25)


@pytest.mark.parametrize('backend', ['float', 'spiking', 'baseline'])
def test_every_estimator_recovers_a_known_pose_through_the_pipeline(backend: str) -> None:
    cfg = from_dict(ResonatorConfig, {'map': {'learn': False}})
    est = (PhaseCorrelationBaseline(config_like(cfg)) if backend == 'baseline' else
           make_backend(cfg, rng=np.random.default_rng(1), backend=backend))
    pipe = OdometryPipeline(est)
    imgs = frames()
    out = [pipe.step(img, i * DT) for i, img in enumerate(imgs)]
    s = pipe.series()
    assert len(s) == pipe.frames == len(imgs) and s.z is None
    np.testing.assert_array_equal(s.t, np.arange(len(imgs)) * DT)
    np.testing.assert_array_equal(s.h, [e.h for e in out])
    np.testing.assert_array_equal(s.r, [e.r for e in out])
    got = np.array([s.h[-1], s.v[-1], s.r[-1]])
    assert np.all(np.abs(got - POSE) <= (0.6, 0.6, 0.03)), (backend, got)


def test_pipeline_equals_stepping_the_estimator_by_hand() -> None:
    cfg = from_dict(ResonatorConfig, {'cleanup': {'gamma': 0.6}})
    imgs = frames(25, seed=3)
    hand = make_backend(cfg, rng=np.random.default_rng(7))
    want = [hand.step(img, i * DT) for i, img in enumerate(imgs)]
    pipe = OdometryPipeline(make_backend(cfg, rng=np.random.default_rng(7)), with_z=True)
    for i, img in enumerate(imgs):
        pipe.step(img, i * DT)
    s = pipe.series()
    for col in ('h', 'v', 'r', 'z'):
        np.testing.assert_array_equal(getattr(s, col), [getattr(e, col) for e in want])


def test_gyro_increments_predict_each_frame() -> None:
    t_imu = np.arange(0, 101) * 1_000_000                        # 1 kHz for 0.1 s
    rate = np.tile([0.1, -0.2, 0.3], (len(t_imu), 1))           # rad/s, constant
    gyro = GyroIntegrator.from_imu(ImuData(t_imu, np.zeros_like(rate), rate))
    rec = Recorder()
    pipe = OdometryPipeline(rec, gyro=gyro, record=False)
    img = np.zeros((4, 4), np.uint8)
    pipe.step(img, 10_000_000)
    pipe.step(img, 30_000_000)
    pipe.step(img, 35_000_000, use_gyro=False)                  # the IMU switched off
    pipe.step(img, 50_000_000)
    deltas = [d for _, _, d in rec.calls]
    assert deltas[0] is None and deltas[2] is None
    assert deltas[1] is not None and deltas[3] is not None
    np.testing.assert_allclose(deltas[1], [0.002, -0.004, 0.006], atol=1e-15)   # 20 ms
    np.testing.assert_allclose(deltas[3], [0.002, -0.004, 0.006], atol=1e-15)   # 30 -> 50 ms
    assert pipe.frames == 0                                     # record=False keeps nothing


def test_push_packetizes_events_into_frames() -> None:
    rng = np.random.default_rng(5)
    n = 2000 * 7 + 500                                          # 7 packets and a partial one
    t = np.sort(rng.integers(0, 10**9, n))
    x, y = rng.integers(0, 240, n), rng.integers(0, 180, n)
    ev = EventArray.from_arrays(t, x, y, np.zeros(n, np.uint8))
    pcfg = PacketizerConfig(max_frame_ms=0.0)                  # packets by count only
    want = Packetizer(pcfg).push(ev)
    rec = Recorder()
    pipe = OdometryPipeline(rec, packetizer=Packetizer(pcfg), with_z=True)
    got = pipe.push(ev[:5000]) + pipe.push(ev[5000:])          # a frame spans the two pushes
    assert len(got) == len(want) == 7
    for (t_ns, image, delta), frame in zip(rec.calls, want, strict=True):
        assert t_ns == frame.t_ns and delta is None
        np.testing.assert_array_equal(image, frame.image)
    s = pipe.series()
    np.testing.assert_array_equal(s.t, [f.t_ns for f in want])
    np.testing.assert_array_equal(s.h, [float(f.image.sum()) for f in want])
    assert s.z is not None and np.all(s.z == 0.25)
    with pytest.raises(ConfigError, match='packetizer'):
        OdometryPipeline(rec).push(ev)
