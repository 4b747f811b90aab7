"""Fuzz tests: see fuzzlib for the time budget (HRN_FUZZ_SECONDS) and the outcome rule."""

from __future__ import annotations

from pathlib import Path
import sys

sys.path.insert(0, str(Path(__file__).resolve().parent))
