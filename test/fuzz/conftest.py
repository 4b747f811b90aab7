"""Fuzz tests: see fuzzlib for the time budget (HRN_FUZZ_SECONDS) and the outcome rule."""

from __future__ import annotations

from pathlib import Path
import sys

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """A table of the fuzz targets run in this session: seconds, inputs, outcome."""
    import fuzzlib

    if not fuzzlib.RUNS:
        return
    terminalreporter.section('fuzz targets')
    for run in fuzzlib.RUNS:
        terminalreporter.write_line(run.line())
