"""The robustness benchmark's row helpers: the odd-lag note and CSVs written before a column."""

from __future__ import annotations

import math
from pathlib import Path
import sys

import pytest

from hrn_vo_ros.core.sim.family import Draw

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'bench'))
robustness = pytest.importorskip('bench_robustness')


def _row(seed: int, lag_s: float) -> object:
    return robustness.Row('rotation', seed, 'hrn', 10.0, 1e5, 100.0, 0.5, False, 0.0, 0, 0, 0,
                          '', 1.0, '', 'draw', lag_s=lag_s)


def test_only_lags_beyond_a_tenth_of_a_second_are_named() -> None:
    rows = [_row(1, 0.002), _row(2, -0.375), _row(3, 0.1), _row(4, math.nan), _row(5, 0.101)]
    assert robustness._odd_lags(rows) == ', lag beyond ±0.1 s: 2 (-0.38 s) 5 (+0.10 s)'
    assert robustness._odd_lags(rows[:1]) == ''


def test_a_csv_without_the_lag_column_reads_as_unknown_lags(tmp_path: Path) -> None:
    path = tmp_path / 'old.csv'
    header = ('kind,seed,method,seconds,events_per_s,peak,median_err,lost,lost_s,losses,silent,'
              'late,reloc_s,wall_s,note,draw')
    path.write_text(header + '\nrotation,7,hrn,10.0,1000.0,50.0,0.4,False,0.0,0,0,0,,1.0,,d\n')
    (row,) = robustness.read_rows(path)
    assert row.seed == 7 and math.isnan(row.lag_s) and robustness._odd_lags([row]) == ''


def test_a_preset_with_another_kind_or_split_is_refused(
        capsys: pytest.CaptureFixture[str]) -> None:
    for kinds in (['translation'], ['rotation', 'translation', 'arm']):
        assert robustness.main(['--preset', 'shapes_rotation', '--kinds', *kinds]) == 2
        assert '--kinds rotation' in capsys.readouterr().err
    assert robustness.main(['--preset', 'shapes_rotation', '--tuning']) == 2
    assert 'drop --tuning' in capsys.readouterr().err


def test_a_preset_sequence_is_cached_under_its_own_name(tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    """A preset's events never come from the cached draw of the same seed: the family draw's
    events file (junk here) is not read, and the preset itself is simulated."""
    (tmp_path / 'rotation_3_6_events.pkl').write_bytes(b'not a pickle')
    made: list[Draw] = []

    def fake_simulate(d: Draw, seconds: float) -> object:
        made.append(d)
        raise RuntimeError('stop after the draw')

    monkeypatch.setattr(robustness, 'simulate_draw', fake_simulate)
    monkeypatch.setitem(robustness.PRESET, 'name', 'shapes_rotation')
    with pytest.raises(RuntimeError, match='stop after the draw'):
        robustness._frames('rotation', 3, 6.0, str(tmp_path))
    (d,) = made
    assert d.split == 'preset' and d.seed == 3 and d.seconds == 60.0
    assert d.calib.fx == pytest.approx(199.092366542)


def test_the_junk_share_of_a_draw_and_its_band(tmp_path: Path) -> None:
    """Fresh rotation 10045: 0.023 Hz of noise on 240x180 pixels (994 events/s) and 30 hot
    pixels at a nominal 561.7 Hz, which fire at 1.15 times it on average (19379), of 22593
    events/s: 90 %, in the top band; the scene event rate is the rest; a CSV written before the
    column reads as unknown and falls in no band."""
    from hrn_vo_ros.core.sim.family import draw
    d = draw('rotation', 10045)
    c = d.config
    want = (c.noise_rate_hz * 240 * 180 + 30 * c.hot_pixel_rate_hz * 1.15) / 22593.3
    assert (c.hot_pixels, d.calib.width, d.calib.height) == (30, 240, 180)
    assert robustness.junk_share(d, 22593.3) == pytest.approx(want) == pytest.approx(0.9017,
                                                                                      abs=1e-4)
    assert robustness.junk_share(d, 100.0) == 1.0 and robustness.junk_share(d, 0.0) == 1.0
    rows = [robustness.Row('rotation', s, 'hrn', 10.0, 1e5, 100.0, err, False, 0.0, 0, 0, 0, '',
                           1.0, '', 'draw', junk=j)
            for s, err, j in [(1, 0.5, 0.05), (2, 0.5, 0.79), (3, 50.0, 0.5), (4, 0.5, 0.15)]]
    line = robustness.breakdown(rows, ['rotation'], ['hrn'])[1]
    assert 'junk <15% 1/1, 15-50% 1/1, >=50% 1/2' in line
    # scene events/s (1 - junk) x 1e5: 95 k, 21 k, 50 k (the band's lower edge), 85 k
    assert [robustness.scene_rate(r) for r in rows] == pytest.approx([95e3, 21e3, 50e3, 85e3])
    assert line.endswith('>=50% 1/2, 10-50k 1/1, >=50k 2/3, unevaluated few 0 still 0 other 0')
    path = tmp_path / 'old.csv'
    header = ('kind,seed,method,seconds,events_per_s,peak,median_err,lost,lost_s,losses,silent,'
              'late,reloc_s,wall_s,note,draw')
    path.write_text(header + '\nrotation,7,hrn,10.0,1000.0,50.0,0.4,False,0.0,0,0,0,,1.0,,d\n')
    (row,) = robustness.read_rows(path)
    old = robustness.breakdown([row], ['rotation'], ['hrn'])[1]
    assert math.isnan(row.junk) and 'junk' not in old and 'scene <10k' not in old


def test_the_lag0_diagnostic_names_what_the_lag_search_moved(tmp_path: Path) -> None:
    """Tracked with the lag fixed at 0 against the protocol's verdict: gained and lost seeds;
    rows without the figure (older CSVs, failed evaluations) are left out, and with none the
    line is not printed."""
    def row(seed: int, err: float, lag0: bool | None) -> object:
        return robustness.Row('rotation', seed, 'hrn', 10.0, 1e5, 100.0, err, False, 0.0, 0, 0,
                              0, '', 1.0, '', 'draw', tracked_lag0=lag0)
    rows = [row(1, 0.5, True), row(2, 18.8, True), row(3, 0.4, False), row(4, 0.3, None),
            row(5, 30.0, False)]
    assert robustness._lag0_line('rotation', 'hrn', rows) == (
        'rotation     hrn       tracked 2/4 (gained: 2; lost: 3)')
    assert robustness._lag0_line('rotation', 'hrn', rows[3:4]) == ''
    path = tmp_path / 'rows.csv'
    path.write_text('kind,seed,method,seconds,events_per_s,peak,median_err,lost,lost_s,losses,'
                    'silent,late,reloc_s,wall_s,note,draw,tracked_lag0\n'
                    'rotation,7,hrn,10.0,1000.0,50.0,0.4,False,0.0,0,0,0,,1.0,,d,True\n'
                    'rotation,8,hrn,10.0,1000.0,50.0,0.4,False,0.0,0,0,0,,1.0,,d,\n')
    a, b = robustness.read_rows(path)
    assert a.tracked_lag0 is True and b.tracked_lag0 is None
    lines = robustness.breakdown([a, b], ['rotation'], ['hrn'])
    assert lines[-1] == 'rotation     hrn       tracked 1/1 (gained: -; lost: -)'


def test_the_motion_per_frame_bands() -> None:
    """Rotation rows fall in the degree bands at their edges (2 and 4 in the upper band),
    translation rows in the cm bands (the CSV's metres x 100); rows without the figure in none."""
    rows = [robustness.Row(kind, s, 'hrn', 10.0, 1e5, 100.0, 0.01, False, 0.0, 0, 0, 0, '', 1.0,
                           '', 'draw', frame_deg=deg_, frame_m=m_)
            for kind, s, deg_, m_ in [('rotation', 1, 1.9, 0.0), ('rotation', 2, 2.0, 0.0),
                                      ('rotation', 3, 4.0, 0.0), ('rotation', 6, math.nan, 0.0),
                                      ('translation', 4, 0.1, 0.004),
                                      ('translation', 5, 0.1, 0.01)]]
    lines = robustness.breakdown(rows, ['rotation', 'translation'], ['hrn'])
    assert lines[1].endswith('<2 deg/frame 1/1, 2-4 1/1, >=4 1/1, '
                             'unevaluated few 0 still 0 other 0')
    assert '<0.5 cm/frame 1/1, >=1 1/1, unevaluated' in lines[2]


def test_the_frame_structure_bands(tmp_path: Path) -> None:
    """Rows fall in the structure bands at their edges (1.5 and 3 in the upper band), a row
    without the figure in none; the figure reads back from a CSV written as the bench writes
    it."""
    rows = [robustness.Row('rotation', s, 'hrn', 10.0, 1e5, 100.0, err, False, 0.0, 0, 0, 0,
                           '', 1.0, '', 'draw', structure=x)
            for s, err, x in [(1, 50.0, 1.49), (2, 0.5, 1.5), (3, 0.5, 3.0), (4, 0.5, 2.9),
                              (5, 0.5, math.nan)]]
    line = robustness.breakdown(rows, ['rotation'], ['hrn'])[1]
    assert line.endswith('structure <1.5 0/1, 1.5-3 2/2, >=3 1/1, '
                         'unevaluated few 0 still 0 other 0')
    assert 'structure' in robustness.breakdown(rows, ['rotation'], ['hrn'])[0]
    path = tmp_path / 'rows.csv'
    robustness.write_rows(path, rows)
    back = robustness.read_rows(path)
    assert [r.structure for r in back[:4]] == [1.49, 1.5, 3.0, 2.9]
    assert math.isnan(back[4].structure)


def test_the_sign_test_of_a_paired_split_is_the_exact_binomial_tail() -> None:
    # 8 / 1: 2 (C(9,0) + C(9,1)) / 2^9 = 20 / 512; 5 / 0: 2 / 32; 4 / 4 and 0 / 0: 1
    assert robustness.sign_test_p(8, 1) == robustness.sign_test_p(1, 8) == 20 / 512
    assert robustness.sign_test_p(5, 0) == 0.0625
    assert robustness.sign_test_p(4, 4) == robustness.sign_test_p(0, 0) == 1.0
    assert robustness.sign_test_p(3, 1) == 2 * 5 / 16


def _verdicts(method: str, errs: dict[int, float]) -> list[object]:
    return [robustness.Row('rotation', s, method, 10.0, 1e5, 100.0, e, False, 0.0, 0, 0, 0, '',
                           1.0, '', 'draw') for s, e in errs.items()]


def test_paired_runs_are_compared_draw_by_draw_on_the_draws_all_have(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Draw 5 is only in run a (left out); a 20° median is a loss, 0.5° a track."""
    t, lost = 0.5, 20.0
    a = (_verdicts('hrn', {1: t, 2: t, 3: lost, 4: t, 5: t})
         + _verdicts('spiking', {1: t, 2: lost, 3: lost, 4: t, 5: lost}))
    b = _verdicts('hrn', {1: t, 2: lost, 3: lost, 4: lost})
    lines = robustness.paired([('a', a), ('b', b)], ['rotation'])
    assert lines == [
        'rotation: 4 draws in all 3 columns',
        '  a/hrn                        tracked 3',
        '  a/spiking                    tracked 2',
        '  b/hrn                        tracked 1',
        '  hrn: mean 2.0 over 2 runs (range 1-3)',
        '  not tracked alike: 2 draws (a/hrn a/spiking b/hrn)',
        '    2  T L L',
        '    4  T T L',
        '  a/hrn vs a/spiking: 1 / 0 tracked by one only, sign test p 1',
        '  a/hrn vs b/hrn: 2 / 0 tracked by one only, sign test p 0.5',
        '  a/spiking vs b/hrn: 1 / 0 tracked by one only, sign test p 1']
    paths = []
    for name, rows in (('a', a), ('b', b)):
        paths.append(tmp_path / f'{name}.csv')
        with open(paths[-1], 'w', newline='') as f:
            w = robustness.csv.DictWriter(f, fieldnames=list(robustness.asdict(rows[0])))
            w.writeheader()
            w.writerows(robustness.asdict(r) for r in rows)
    assert robustness.main(['--rows', *map(str, paths), '--paired']) == 0
    assert capsys.readouterr().out.splitlines() == lines
    assert robustness.paired([('b', b)], ['rotation']) == [
        'rotation: 1 column (run and method): nothing to pair; give --rows files of runs on '
        'the same draws']
    assert robustness.main(['--paired']) == 2
    assert '--rows' in capsys.readouterr().err


def test_the_verdict_map_places_each_draw_at_its_scene_rate_and_motion() -> None:
    """One point per draw with both figures, at (events/s x (1 - junk), turn per frame),
    tracked as dots and lost ones (a loss or a median beyond 10 deg) as crosses."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    def row(seed: int, rate: float, junk: float, deg: float, err: float,
            lost: bool = False) -> object:
        return robustness.Row('rotation', seed, 'hrn', 10.0, rate, 100.0, err, lost, 0.0, 0,
                              0, 0, '', 1.0, '', 'draw', junk=junk, frame_deg=deg)

    rows = [row(1, 1e5, 0.5, 2.0, 0.4), row(2, 4e3, 0.0, 8.0, 0.3, lost=True),
            row(3, 2e4, 0.75, 1.0, 12.0), row(4, 1e5, math.nan, 1.0, 0.2)]   # 4: no junk
    fig, ax = plt.subplots()
    robustness._verdict_map(ax, rows, 'rotation', 'hrn')
    dots, crosses = ax.get_lines()
    assert list(zip(dots.get_xdata(), dots.get_ydata(), strict=True)) == [(5e4, 2.0)]
    assert list(zip(crosses.get_xdata(), crosses.get_ydata(), strict=True)) == [
        (4e3, 8.0), (5e3, 1.0)]
    assert ax.get_title() == 'rotation, hrn: tracked 1/3'
    plt.close(fig)


@pytest.mark.parametrize('args, says', [
    (['--sset', 'spiking.phase_rounding=stochastic'],
     'no SpikingConfig field spiking.phase_rounding'),
    (['--sset', 'phase_rounding=sometimes'], 'phase_rounding'),
    (['--set', 'cleanup.gama=0.5'], 'unknown CleanupConfig key(s) gama'),
    (['--pset', 'events_per_frame=-3'], 'events_per_frame'),
])
def test_bad_overrides_are_refused_before_any_draw_runs(
        args: list[str], says: str, capsys: pytest.CaptureFixture[str]) -> None:
    """A mistyped or invalid override stops the run up front (exit 2, naming it), where each
    worker would otherwise fail on it one draw at a time and the table read 0 tracked."""
    assert robustness.main(['--kinds', 'rotation', '--seeds', '10000', *args]) == 2
    err = capsys.readouterr().err
    assert says in err, err
