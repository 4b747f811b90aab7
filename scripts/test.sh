#!/usr/bin/env bash
# The project's test command: set up (or re-use) the environment, then lint, type-check and test.
# Extra arguments go to pytest, e.g. scripts/test.sh -k resonator -x
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
scripts/setup.sh
echo "[test] ruff (99 columns, as ament_flake8)"
scripts/run.sh ruff check .
echo "[test] mypy --strict (core, io)"
scripts/run.sh mypy
echo "[test] pytest"
scripts/run.sh python -m pytest "$@"
