"""Mutation check of one module: do its tests fail when the code has a small bug?

Each mutant changes one token of the module (a comparison's bound, an arithmetic operator,
``and``/``or``, ``True``/``False``, ``min``/``max``, a dropped ``not``, an integer constant
plus one); the given tests run against it in a scratch copy of the repository, and a mutant
they still pass is printed as a survivor. Survivors are test gaps, or mutants that change
nothing observable (an extra copy, a bound no input reaches): read each one. Strings,
comments, docstrings and decorator lines are never mutated.

    scripts/run.sh python scripts/mutants.py hrn_vo_ros/core/clock.py test/core/test_clock.py
    scripts/run.sh python scripts/mutants.py MODULE TESTS... --jobs 2 --lines 113,115

Exit codes: 0 the report is printed (survivors or not), 2 bad arguments or the tests fail on
the unchanged code. A development tool: it copies the package, tests, configs and benchmarks
into a temporary directory per job and runs ``python -m pytest -x -q`` there with that copy
first on ``PYTHONPATH``.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
import io
import os
from pathlib import Path
import queue
import shutil
import subprocess
import sys
import tempfile
import time
import tokenize

ROOT = Path(__file__).resolve().parents[1]
COPIED = ('hrn_vo_ros', 'test', 'config', 'bench', 'pyproject.toml')

#: Token replacements: operators and names (each occurrence gives one mutant per entry).
SWAPS: dict[str, tuple[str, ...]] = {
    '<': ('<=',), '<=': ('<',), '>': ('>=',), '>=': ('>',), '==': ('!=',), '!=': ('==',),
    '+': ('-',), '-': ('+',), '*': ('/',), '/': ('*',), '//': ('*',),
    'and': ('or',), 'or': ('and',), 'True': ('False',), 'False': ('True',),
    'min': ('max',), 'max': ('min',), 'not': ('',),
}


@dataclass(frozen=True, slots=True)
class Mutant:
    """One token of the module replaced: 1-based line, column, old and new text."""

    line: int
    col: int
    old: str
    new: str

    def apply(self, lines: list[str]) -> list[str]:
        """The module's lines with this mutant applied."""
        out = list(lines)
        s = out[self.line - 1]
        out[self.line - 1] = s[:self.col] + self.new + s[self.col + len(self.old):]
        return out


def mutants(source: str) -> list[Mutant]:
    """Every mutant of ``source``, in source order (module code only, see the docstring)."""
    lines = source.splitlines(keepends=True)
    out = []
    prev = ''
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        line, col = tok.start
        before, prev = prev, tok.string
        if (line > len(lines) or tok.start[0] != tok.end[0]
                or lines[line - 1].lstrip().startswith('@')):
            continue
        if tok.string in ('*', '/') and before in ('(', ','):
            continue                    # a signature's bare * or /, or *args: no operator
        if tok.type in (tokenize.OP, tokenize.NAME) and tok.string in SWAPS:
            out += [Mutant(line, col, tok.string, new) for new in SWAPS[tok.string]]
        elif tok.type == tokenize.NUMBER and tok.string.isdigit():
            out.append(Mutant(line, col, tok.string, str(int(tok.string) + 1)))
    return out


def _copy_tree(dest: Path) -> None:
    for name in COPIED:
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns('__pycache__'))
        elif src.exists():
            shutil.copy2(src, dest / name)


def _passes(tree: Path, tests: list[str], timeout: float) -> bool:
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_NUM_THREADS='1',
               OPENBLAS_NUM_THREADS='1')
    try:
        r = subprocess.run([sys.executable, '-m', 'pytest', '-x', '-q', '-p', 'no:cacheprovider',
                            *tests], cwd=tree, env=env, capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return False                    # a mutant that hangs the tests is caught
    return r.returncode == 0


def main(argv: list[str] | None = None) -> int:
    """Run the mutation check; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('module', help='the module to mutate, relative to the repository')
    ap.add_argument('tests', nargs='+', help='test files (or node ids) that should catch it')
    ap.add_argument('--jobs', type=int, default=2, help='mutants tested at once')
    ap.add_argument('--lines', default='', help='only these 1-based lines, comma-separated')
    ap.add_argument('--timeout', type=float, default=300.0, help='seconds per test run')
    args = ap.parse_args(argv)
    module = Path(args.module)
    if module.is_absolute() or not (ROOT / module).is_file() or module.suffix != '.py':
        print(f'mutants: {args.module} is not a Python module of the repository (give its '
              'path relative to the repository root)', file=sys.stderr)
        return 2
    source = (ROOT / module).read_text()
    found = mutants(source)
    if args.lines:
        try:
            keep = {int(x) for x in args.lines.split(',')}
        except ValueError:
            print(f'mutants: --lines {args.lines!r}: give line numbers like 12,40',
                  file=sys.stderr)
            return 2
        found = [m for m in found if m.line in keep]
    lines = source.splitlines(keepends=True)
    trees: queue.Queue[Path] = queue.Queue()
    with tempfile.TemporaryDirectory(prefix='hrn-mutants-') as tmp:
        for j in range(max(1, args.jobs)):
            tree = Path(tmp) / f'job{j}'
            _copy_tree(tree)
            trees.put(tree)
        first = trees.get()
        if not _passes(first, args.tests, args.timeout):
            print('mutants: the tests fail on the unchanged code: fix them first', file=sys.stderr)
            return 2
        trees.put(first)
        print(f'{module}: {len(found)} mutants, tests {" ".join(args.tests)}', flush=True)
        t0 = time.monotonic()

        def run(m: Mutant) -> tuple[Mutant, bool]:
            tree = trees.get()
            target = tree / module
            try:
                target.write_text(''.join(m.apply(lines)))
                return m, _passes(tree, args.tests, args.timeout)
            finally:
                target.write_text(source)
                trees.put(tree)

        survivors = []
        with ThreadPoolExecutor(max(1, args.jobs)) as ex:
            for i, (m, alive) in enumerate(ex.map(run, found), start=1):
                if alive:
                    survivors.append(m)
                    print(f'  survived {module}:{m.line}: {m.old!r} -> {m.new!r}: '
                          f'{m.apply(lines)[m.line - 1].strip()}', flush=True)
                if i % 20 == 0:
                    print(f'  ... {i}/{len(found)} mutants, {time.monotonic() - t0:.0f} s',
                          flush=True)
    print(f'{len(survivors)} of {len(found)} mutants survived')
    return 0


if __name__ == '__main__':
    sys.exit(main())
