"""Every benchmark in ``bench/`` runs to the end at tiny sizes (no figure is checked).

Each script runs as ``scripts/run.sh python bench/X.py`` would (a subprocess of this
interpreter, the working tree on ``PYTHONPATH``), with its ``--smoke`` option or the smallest
sizes its options allow; the test asserts exit 0, the last line of its table and no failed
step, so that a benchmark cannot rot unnoticed. The figures themselves are meaningless at these
sizes.
"""

from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / 'bench'


@dataclass(frozen=True)
class Case:
    """One benchmark run: its arguments (``{work}``: a scratch folder) and what it must print."""

    script: str
    args: tuple[str, ...]
    expect: tuple[str, ...]
    timeout: float = 120.0
    then: tuple[str, ...] = ()          # a second run's arguments (after the first's)
    then_expect: tuple[str, ...] = ()


CASES = {
    'convert': Case('bench_convert.py', ('--smoke',),
                    ('convert to MCAP', 'evt3 decode', 'ratios: convert/parse')),
    'hrn_speed': Case('bench_hrn_speed.py', ('--smoke',),
                      ('fast path', 'dense path', 'ratio dense/fast',
                       'rectify equidistant (')),
    # 1 s is the shortest simulated sequence; 60 frames keep the spiking emulation short (the
    # geodesic columns then read "not evaluated": the lag search needs > 2 s)
    'spiking': Case('bench_spiking.py', ('--seeds', '1', '--seconds', '1', '--frames', '60',
                                         '--layers'),
                    ('seed   1: 60 frames', 'frames/s (median per-frame time)',
                     'payload rounding per population', "Λ': fft_x stages")),
    # the precision sweep's every row (T x weight bits, the ablations) on 20 frames
    'spiking_sweep': Case('bench_spiking.py', ('--seeds', '1', '--seconds', '1', '--frames',
                                               '20', '--sweep'),
                          ('| 63 | 8-bit |', '| 32 | 8-bit, dense reference |',
                           '| 32 | 8-bit, 12-bit transform payloads |',
                           '| 32 | 8-bit, stochastic rounding |'), timeout=240.0),
    # 2.5 s: the evaluation's lag search needs more than 2 s of overlap
    'accuracy': Case('bench_accuracy.py', ('--kinds', 'rotation', '--seeds', '1', '--seconds',
                                           '2.5', '--work', '{work}'),
                     ('Accuracy on simulated 2.5 s sequences', 'within target',
                      'wall time rotation'), timeout=300.0),
    # (with the live camera's config: any sensor size, the rate cap's frame mapping; and a
    # resonator parameter, the frame queue's depth)
    'latency': Case('bench_latency.py', ('--smoke', '--work', '{work}', '--config',
                                         'config/live.yaml', '--rset', 'frames_depth=10'),
                    ('frames expected', 'live.yaml', 'frames_depth=10', 'end-to-end latency',
                     'targets (no drop'),
                    timeout=180.0),
    # its --smoke runs every kind and method (minutes): one kind, the HRN only (the spiking
    # backend and the baseline run in the cases above); 6 s is the shortest the protocol's
    # calibration segment evaluates
    # (with the denoising filter and the live camera's config on a 16:9 320x180 sensor, then its
    # CSV printed again by --rows; --sset is parsed but sets only the spiking method, not run)
    'robustness': Case('bench_robustness.py', ('--smoke', '--kinds', 'rotation', '--methods',
                                               'hrn', '--jobs', '1', '--pset', 'denoise_ms=2',
                                               '--sset', 'precision=float',
                                               '--config', 'config/live.yaml',
                                               '--sensor', '320x180', '--csv', '{work}/r.csv',
                                               '--trace', '{work}/tr'),
                       ('1 sequences in', 'config config/live.yaml',
                        'sensor 320 px wide, 180 high',
                        'tracked  time ok',
                        'rotation     hrn',
                        'background noise', ' Hz ', "frames' structure", 'unevaluated few',
                        'reported as tracking only', 'hrn       silent ',
                        '1 CSV, 1 PNG'),
                       then=('--rows', '{work}/r.csv', '--plot', '{work}/r.png'),
                       then_expect=('tracked  time ok', 'rotation     hrn', 'plot ->',
                                    'hrn       silent ')),
    # the 60 s shapes_rotation-like preset, its first 6 s
    'robustness_preset': Case('bench_robustness.py', ('--preset', 'shapes_rotation', '--smoke',
                                                      '--methods', 'hrn', '--jobs', '1'),
                              ('1 sequences (preset shapes_rotation seeds 0..0, 6 s)',
                               'tracked  time ok', 'rotation     hrn')),
    # one fresh draw, 7 s, its events removed over the first 10-degree turn from 3 s
    'blackout': Case('bench_blackout.py', ('--smoke', '--jobs', '1', '--csv', '{work}.csv'),
                     ('1 rotation draws', 'events removed', 're-localised:', 'median fr',
                      'hrn_imu ', 'rows ->')),
    # two 2.5 s loops of the demo bag through the real node processes
    'soak': Case('bench_soak.py', ('--smoke', '--work', '{work}'),
                 ('RSS summary (MB)', 'from warm-up', 'single pass (offline',
                  'per-loop accuracy', 'loop   2:', 'targets: RSS growth', 'soak done'),
                 timeout=240.0),
}
SLOW = {'accuracy', 'blackout', 'latency', 'robustness', 'robustness_preset', 'soak',
        'spiking_sweep'}
ROS = {'latency', 'soak'}


def _param(name: str) -> object:
    marks = ([pytest.mark.slow] if name in SLOW else []) + ([pytest.mark.ros] if name in ROS
                                                           else [])
    return pytest.param(name, marks=marks, id=name)


@pytest.mark.parametrize('name', [_param(n) for n in CASES])
def test_bench_runs_to_the_end(name: str, tmp_path: Path) -> None:
    case = CASES[name]
    script = BENCH / case.script
    if not script.exists():
        pytest.skip(f'{script.relative_to(ROOT)} does not exist (yet)')
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get('PYTHONPATH')])])}
    runs = [(case.args, case.expect)] + ([(case.then, case.then_expect)] if case.then else [])
    for run_args, expect in runs:
        args = [a.replace('{work}', str(tmp_path / 'work')) for a in run_args]
        proc = subprocess.run([sys.executable, str(script), *args], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=case.timeout,
                              check=False)
        out = proc.stdout + proc.stderr
        assert proc.returncode == 0, f'{case.script} exited with {proc.returncode}:\n{out[-4000:]}'
        missing = [e for e in expect if e not in proc.stdout]
        assert not missing, f'{case.script} did not print {missing}:\n{out[-4000:]}'
        for bad in ('Traceback', 'FAILED'):
            assert bad not in out, f'{case.script} printed {bad!r}:\n{out[-4000:]}'
