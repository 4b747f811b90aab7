#!/usr/bin/env bash
# Run one command inside the project environment made by scripts/setup.sh.
# Example: scripts/run.sh hrn-vo simulate /tmp/seq --kind rotation --seconds 20 --seed 3
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
VENV=${HRN_VENV:-$ROOT/.venv}
if [ ! -f "$VENV/hrn_env.sh" ]; then
    echo "[run] no environment yet: run scripts/setup.sh first" >&2
    exit 2
fi
# shellcheck source=/dev/null
source "$VENV/hrn_env.sh"
exec "$@"
