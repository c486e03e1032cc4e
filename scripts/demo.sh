#!/usr/bin/env bash
# Main job: set up everything, run the default scene (runs/demo.nml) with a
# progress bar, write its plots to runs/out/demo/plots (replacing an earlier demo run there).
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
source "$ROOT/scripts/setup.sh"
cd "$ROOT"
scene=${1:-runs/demo.nml}
shift || true
name=$(basename "$scene" .nml)
exec "$VENV/bin/pyorch" run "$scene" --out "runs/out/$name" --overwrite "$@"
