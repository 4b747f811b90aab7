"""Backend conformance: every registered backend runs the same frames to the same answer."""

from __future__ import annotations

from hrn_synth import event_frame, random_scene
import numpy as np
import pytest

from hrn_vo_ros.core.configbase import from_dict
from hrn_vo_ros.core.hrn.backends import (
    BackendConfig,
    BACKENDS,
    make_backend,
    ResonatorBackend,
    SpikingDiagnostics,
)
from hrn_vo_ros.core.hrn.config import paper_config
from hrn_vo_ros.errors import ConfigError

POSE = (4.0, 2.0, 0.2)


@pytest.fixture(scope='module')
def frames() -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    scene = random_scene(rng)
    poses = [(0.0, 0.0, 0.0, 0.0)] + [(*POSE, 0.0)] * 40
    return [event_frame(scene, p, rng) for p in poses]


@pytest.fixture(scope='module')
def results(frames: list[np.ndarray]) -> dict[str, np.ndarray]:
    cfg = paper_config({'map': {'learn': False}})
    out = {}
    for name in BACKENDS:
        b = make_backend(cfg, rng=np.random.default_rng(1), backend=name)
        assert isinstance(b, ResonatorBackend)
        ests = [b.step(f, i * 5_000_000) for i, f in enumerate(frames)]
        assert b.iteration == len(frames)
        assert b.map_image().shape == (cfg.height, cfg.width)
        out[name] = np.array([(e.h, e.v, e.r) for e in ests])
    return out


@pytest.mark.parametrize('name', sorted(BACKENDS))
def test_every_backend_recovers_the_pose(name: str, results: dict[str, np.ndarray]) -> None:
    err = np.abs(results[name][-1] - np.asarray(POSE))
    assert np.all(err <= (0.5, 0.5, 0.03)), (name, results[name][-1])


def test_spiking_matches_float_once_converged(results: dict[str, np.ndarray]) -> None:
    diff = np.abs(results['spiking'][20:] - results['float'][20:])
    assert np.median(diff[:, :2]) <= 0.5 and np.degrees(np.median(diff[:, 2])) <= 1.0, diff[-1]


def test_registry_and_diagnostics() -> None:
    cfg = paper_config()
    spiking = make_backend(cfg, rng=np.random.default_rng(0),
                           backend=BackendConfig(name='spiking'))
    assert isinstance(spiking, SpikingDiagnostics)
    assert not isinstance(make_backend(cfg, rng=np.random.default_rng(0)), SpikingDiagnostics)
    with pytest.raises(ConfigError, match='float, spiking'):
        make_backend(cfg, rng=np.random.default_rng(0), backend='loihi3')
    assert from_dict(BackendConfig, {'name': 'spiking', 'spiking.steps_per_cycle': 16}
                     ).spiking.steps_per_cycle == 16
