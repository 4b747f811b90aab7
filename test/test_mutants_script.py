"""scripts/mutants.py, the mutation check of a module's tests: its mutants by hand, and one
short run end to end (a survivor reported, a bad call refused)."""

from __future__ import annotations

import importlib.util
from pathlib import Path
import subprocess
import sys

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / 'scripts' / 'mutants.py'


def _module():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location('mutants_script', SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules['mutants_script'] = mod         # (dataclasses look the module up)
    spec.loader.exec_module(mod)
    return mod


def test_mutants_of_code_only_by_hand() -> None:
    """Operators, names and integers of the code; nothing in strings, comments, docstrings
    or decorators."""
    src = ('"""a < b"""\n'
           '@dec(x=True)\n'
           'def f(a, *, b):\n'
           '    return a <= 10 and not max(a, b) == "c - d"  # e > f\n')
    found = _module().mutants(src)
    got = [(m.line, m.col, m.old, m.new) for m in found]
    assert got == [(4, 13, '<=', '<'), (4, 16, '10', '11'), (4, 19, 'and', 'or'),
                   (4, 23, 'not', ''), (4, 27, 'max', 'min'), (4, 37, '==', '!=')]
    m = found[2]
    assert m.apply(src.splitlines(keepends=True))[3] == \
        '    return a <= 10 or not max(a, b) == "c - d"  # e > f\n'


def test_a_short_run_reports_the_survivor() -> None:
    """The throttle's line against a test that never meets a nonzero last time: of its four
    mutants only ``now + last`` survives."""
    line = next(i for i, s in enumerate((ROOT / 'hrn_vo_ros/core/clock.py').read_text()
                                        .splitlines(), start=1) if 'now - last < period_s' in s)
    r = subprocess.run([sys.executable, str(SCRIPT), 'hrn_vo_ros/core/clock.py',
                        'test/core/test_clock.py::test_throttle_is_per_key', '--jobs', '1',
                        '--lines', str(line)], cwd=ROOT, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    assert f"survived hrn_vo_ros/core/clock.py:{line}: '-' -> '+'" in r.stdout
    assert '1 of 4 mutants survived' in r.stdout
    bad = subprocess.run([sys.executable, str(SCRIPT), '/etc/passwd', 'test'], cwd=ROOT,
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and 'relative to the repository' in bad.stderr
