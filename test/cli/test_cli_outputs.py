"""Output paths are checked before a command runs; float options refuse NaN and infinities."""

from __future__ import annotations

from pathlib import Path

import pytest

from hrn_vo_ros.cli.main import build_parser, main

FIXTURES = Path(__file__).resolve().parents[1] / 'fixtures'


@pytest.mark.parametrize('argv', [
    ['run', str(FIXTURES / 'seq1s'), '--out', '{missing}/est.csv'],
    ['run', str(FIXTURES / 'seq1s'), '--out', '{tmp}/est.csv', '--tum', '{missing}/est.tum'],
    ['convert', str(FIXTURES / 'seq1s'), '{missing}/bag'],
    ['simulate', '{missing}/seq', '--kind', 'rotation', '--seconds', '1'],
])
def test_an_output_in_a_missing_folder_fails_before_the_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    missing = tmp_path / 'no' / 'such'
    args = [a.format(missing=missing, tmp=tmp_path) for a in argv]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f'the folder {missing} does not exist' in err
    assert not (tmp_path / 'no').exists() and not (tmp_path / 'est.csv').exists()


def test_a_file_output_that_is_a_folder_is_refused(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['run', str(FIXTURES / 'seq1s'), '--out', str(tmp_path)]) == 2
    assert f'--out {tmp_path} is a folder' in capsys.readouterr().err


@pytest.mark.parametrize('argv', [
    ['convert', 'src', 'dst', '--packet-duration', 'nan'],
    ['convert', 'src', 'dst', '--packet-duration', 'inf'],
    ['simulate', 'out', '--seconds', 'nan'],
    ['simulate', 'out', '--seconds=-inf'],
    ['evaluate', 'ds', 'est.csv', '--kind', 'rotation', '--lag', 'NaN'],
    ['demo', '--seconds', 'Infinity'],
    ['play', 'bag', '--rate', 'nan'],
])
def test_float_options_refuse_nan_and_infinity_at_parse_time(
        capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(argv)
    assert exc.value.code == 2
    assert 'expected a finite number' in capsys.readouterr().err


def test_finite_float_options_still_parse() -> None:
    args = build_parser().parse_args(['convert', 'src', 'dst', '--packet-duration', '2.5'])
    assert args.packet_duration == 2.5
