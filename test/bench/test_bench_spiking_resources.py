"""``bench/bench_spiking.py --resources`` runs to the end at a tiny size (figures not checked)."""

from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[2]


def test_bench_spiking_resources_runs_to_the_end() -> None:
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get('PYTHONPATH')])])}
    proc = subprocess.run([sys.executable, str(ROOT / 'bench' / 'bench_spiking.py'), '--seeds',
                           '1', '--seconds', '1', '--frames', '12', '--resources'],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300,
                          check=False)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-4000:]
    for text in ('seed   1: 12 frames', 'resources (hrn-vo spiking-report)',
                 'fits one Loihi 2 chip', 'dense reference', 'CPU, float fast path'):
        assert text in proc.stdout, (text, out[-4000:])
    assert 'Traceback' not in out
