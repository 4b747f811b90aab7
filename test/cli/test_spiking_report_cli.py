"""``hrn-vo spiking-report CONFIG``: the sparse network's resources and measured activity."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrn_vo_ros.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / 'config' / 'shapes_rotation.yaml'


def test_static_report_of_shapes_rotation_fits_one_loihi2(capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    assert main(['spiking-report', str(CONFIG), '--static']) == 0
    out = capsys.readouterr().out
    assert 'designed to Loihi 2' in out and 'fits one Loihi 2 chip: yes' in out
    assert "Λ': fft_y stages" in out and 'critical path: ' in out
    assert 'measured on' not in out


def test_measured_report_prints_synops_energy_time_and_cpu(capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    code = main(['spiking-report', str(CONFIG), '--seconds', '0.3', '--frames', '8',
                 '--no-dense', '--set', 'spiking.steps_per_cycle=16'])
    assert code == 0
    out = capsys.readouterr().out
    assert 'measured on 8 event frames' in out
    for text in ('synaptic ops (<= 2e+06', 'energy ', 'time ', 'CPU, float fast path',
                 'emulation frames/s', 'Davies et al.', 'steps_per_cycle=16'):
        assert text in out, text
    assert 'dense reference' not in out


def test_bad_inputs_are_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['spiking-report', str(tmp_path / 'none.yaml'), '--static']) != 0
    assert 'not found' in capsys.readouterr().err
    assert main(['spiking-report', str(CONFIG), '--static', '--set',
                 'spiking.steps_per_cycle=64']) != 0
    assert 'max_delay' in capsys.readouterr().err
    translation = ROOT / 'config' / 'shapes_translation.yaml'
    assert main(['spiking-report', str(translation), '--static']) != 0
    assert 'dense form only' in capsys.readouterr().err
