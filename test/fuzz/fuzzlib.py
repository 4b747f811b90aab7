"""The fuzz harness: a time budget per target, seed corpora, mutations, the outcome rule.

Each target runs for ``HRN_FUZZ_SECONDS`` seconds (default 5; ``.ci/run`` sets 60): the
hypothesis test is run again and again, 50 fresh examples a round, until the budget is spent.
The only acceptable outcomes of a decoder or reader are a valid result or a package error
(:class:`~hrn_vo_ros.errors.HrnVoError`); anything else fails the test with the input that
caused it (hypothesis shrinks it and prints it).

Every run of a target is recorded (:class:`FuzzRun`: seconds, inputs tried, rounds, outcome):
kept in :data:`RUNS` for the ``[fuzz]`` lines of pytest's session summary (``conftest``) and
appended as a JSON line to the file named by ``HRN_FUZZ_REPORT`` when it is set (``run_fuzz``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
import functools
import json
import os
from pathlib import Path
import time
from typing import Any, cast, TypeVar

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from hrn_vo_ros.errors import HrnVoError

CORPUS = Path(__file__).resolve().parent / 'corpus'
FUZZ_SECONDS = float(os.environ.get('HRN_FUZZ_SECONDS', '5'))
ROUND = settings(max_examples=50, deadline=2000, database=None, derandomize=False,
                 suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                        HealthCheck.filter_too_much])
"""Settings of one round: 50 examples, each within 2 s."""

T = TypeVar('T')


@dataclass(frozen=True)
class FuzzRun:
    """One target's run: how long, how many inputs, and how it ended."""

    target: str
    budget_s: float
    seconds: float
    inputs: int
    rounds: int
    outcome: str
    """``ok``, or ``failed: <exception type>`` (the inputs then include hypothesis' shrinking)."""

    def line(self) -> str:
        """The ``[fuzz]`` line of the log."""
        return (f'[fuzz] {self.target}: {self.seconds:.1f} s (budget {self.budget_s:g} s), '
                f'{self.inputs} inputs in {self.rounds} rounds: {self.outcome}')


RUNS: list[FuzzRun] = []
"""The runs of this process, in order."""


def _current_target() -> str:
    """The running pytest item (``test_fuzz_mono``, ``test_fuzz_ros2_bag[mcap]``)."""
    current = os.environ.get('PYTEST_CURRENT_TEST', 'unknown (call)')
    return current.split('::')[-1].rsplit(' (', 1)[0]


def _record(run: FuzzRun) -> None:
    RUNS.append(run)
    report = os.environ.get('HRN_FUZZ_REPORT')
    if report:
        with open(report, 'a', encoding='utf-8') as f:
            f.write(json.dumps(asdict(run)) + '\n')


def run_for(test: Callable[[], None], seconds: float = FUZZ_SECONDS) -> FuzzRun:
    """Run the hypothesis test ``test`` round after round for ``seconds``; the run's record.

    The inputs are counted by wrapping hypothesis' documented hook ``test.hypothesis.inner_test``
    (each call is one example run through the target's body).
    """
    handle = cast(Any, test).hypothesis  # set by hypothesis' @given
    inner = handle.inner_test
    calls = 0

    @functools.wraps(inner)   # hypothesis names the failing case after the target's body
    def counting(*args: Any, **kwargs: Any) -> Any:
        nonlocal calls
        calls += 1
        return inner(*args, **kwargs)

    handle.inner_test = counting
    start = time.monotonic()
    end = start + seconds
    rounds = 0
    result = 'ok'
    try:
        while True:
            test()
            rounds += 1
            if time.monotonic() >= end:
                break
    except BaseException as err:
        result = f'failed: {type(err).__name__}'
        raise
    finally:
        handle.inner_test = inner
        _record(FuzzRun(_current_target(), seconds, time.monotonic() - start, calls, rounds,
                        result))
    return RUNS[-1]


def outcome(fn: Callable[..., T], *args: Any, **kwargs: Any) -> T | HrnVoError:
    """``fn(*args, **kwargs)``, or the package error it raised (any other error propagates)."""
    try:
        return fn(*args, **kwargs)
    except HrnVoError as err:
        assert str(err), 'a package error must say what is wrong'
        return err


def seeds(name: str) -> list[bytes]:
    """The committed seed inputs of a target (``corpus/<name>/*``)."""
    folder = CORPUS / name
    return [p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()]


@st.composite
def mutated(draw: st.DrawFn, corpus: list[bytes], *, max_edits: int = 8) -> bytes:
    """A seed with a few random edits: byte flips, overwrites, inserts, deletions, truncation."""
    data = bytearray(draw(st.sampled_from(corpus)))
    for _ in range(draw(st.integers(0, max_edits))):
        kind = draw(st.sampled_from(['flip', 'set', 'insert', 'delete', 'truncate', 'block']))
        i = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == 'flip' and data:
            data[i] ^= 1 << draw(st.integers(0, 7))
        elif kind == 'set' and data:
            data[i] = draw(st.sampled_from([0, 1, 0x7F, 0x80, 0xFF, draw(st.integers(0, 255))]))
        elif kind == 'insert':
            data[i:i] = draw(st.binary(min_size=1, max_size=16))
        elif kind == 'delete' and data:
            del data[i:i + draw(st.integers(1, 16))]
        elif kind == 'truncate':
            del data[i:]
        elif kind == 'block' and data:
            n = draw(st.integers(1, 256))
            data[i:i + n] = bytes(b ^ 0xFF for b in data[i:i + n])
    return bytes(data)


def inputs(corpus: list[bytes], *, max_size: int = 4096) -> st.SearchStrategy[bytes]:
    """Random bytes or mutated seeds (mostly the latter: they reach deeper)."""
    return st.one_of(st.binary(max_size=max_size), mutated(corpus), mutated(corpus),
                     mutated(corpus))
