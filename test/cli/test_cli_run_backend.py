"""``hrn-vo run --backend spiking``: the spiking emulation on a dataset, settings via --set."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hrn_vo_ros.cli.main import main
from hrn_vo_ros.core.events.arrays import EventArray
from hrn_vo_ros.core.events.sequence import CameraCalibration, Sequence
from hrn_vo_ros.io import ecd


@pytest.fixture(scope='module')
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rng = np.random.default_rng(0)
    n = 12_000                                  # six packets of 2000 events
    t = 1_000_000 + np.cumsum(rng.integers(1, 3000, n))
    # A few bright blobs that drift right: frames with structure, not uniform noise.
    cx = rng.choice([40, 90, 150, 200], n) + (t - t[0]) // 2_000_000
    cy = rng.choice([30, 80, 140], n)
    x = np.clip(cx + rng.integers(-6, 7, n), 0, 239)
    y = np.clip(cy + rng.integers(-6, 7, n), 0, 179)
    ev = EventArray.from_arrays(t, x, y, rng.integers(0, 2, n))
    seq = Sequence(ev, CameraCalibration(240, 180, 199.0, 199.0, 120.0, 90.0))
    return ecd.write_sequence(tmp_path_factory.mktemp('ds') / 'seq', seq)


def test_run_with_the_spiking_backend_writes_estimates(dataset: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'est.csv'
    code = main(['run', str(dataset), '--out', str(out), '--backend', 'spiking', '--quiet',
                 '--set', 'spiking.steps_per_cycle=16', '--set', 'spiking.weight_bits=6'])
    assert code == 0
    lines = out.read_text().strip().splitlines()
    assert len(lines) >= 1 + 6                   # header + one row per packet
    assert 'spiking, per iteration' in capsys.readouterr().out


def test_bad_spiking_settings_are_config_errors(dataset: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    code = main(['run', str(dataset), '--out', str(tmp_path / 'e.csv'), '--backend', 'spiking',
                 '--quiet', '--set', 'spiking.steps_per_cycle=64'])
    assert code == 2
    assert 'steps_per_cycle <= 63' in capsys.readouterr().err
