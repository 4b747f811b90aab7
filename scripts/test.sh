#!/usr/bin/env bash
# The project's test command: set up (or re-use) the environment, then lint, type-check and test.
# Without arguments: pytest (all but test/fuzz), then the fuzz targets as their own step
# (test/fuzz/run_fuzz.py: HRN_FUZZ_SECONDS per target, default 5 s, .ci/run sets 60;
# HRN_FUZZ_JOBS targets at a time, default 2), never alongside the timing-sensitive ROS tests.
# Extra arguments go to one pytest run instead (fuzz targets included when selected, at
# HRN_FUZZ_SECONDS each), e.g. scripts/test.sh -k resonator -x
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$ROOT"
scripts/setup.sh
echo "[test] ruff (99 columns, as ament_flake8)"
scripts/run.sh ruff check .
echo "[test] mypy --strict (core, io)"
scripts/run.sh mypy
if [ $# -gt 0 ]; then
    echo "[test] pytest $*"
    scripts/run.sh python -m pytest "$@"
    exit
fi
echo "[test] pytest (test/fuzz runs next, on its own)"
rc=0
scripts/run.sh python -m pytest --ignore=test/fuzz || rc=$?
echo "[test] fuzz: ${HRN_FUZZ_SECONDS:-5} s per target, ${HRN_FUZZ_JOBS:-2} at a time"
fuzz_start=$(date +%s)
scripts/run.sh python test/fuzz/run_fuzz.py || rc=$((rc ? rc : 1))
echo "[test] fuzz step took $(( $(date +%s) - fuzz_start )) s"
exit "$rc"
