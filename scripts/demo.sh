#!/usr/bin/env bash
# The main job in one command on a fresh machine: set up if needed (idempotent, ~1 s when done
# before), then `hrn-vo demo` with the given arguments, e.g.
#   scripts/demo.sh                              # simulate 20 s, replay through the node graph
#   scripts/demo.sh path/to/shapes_rotation --imu --out /tmp/demo
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$ROOT/scripts/setup.sh"
exec "$ROOT/scripts/run.sh" hrn-vo demo "$@"
