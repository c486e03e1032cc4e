#!/usr/bin/env bash
# Main job: set up everything, run the default scene (runs/demo.nml) with a
# progress bar, write its plots to runs/out/demo/plots (replacing an earlier demo run there)
# and the movie of its particle frames, runs/out/demo/plots/movie.mp4.
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
source "$ROOT/scripts/setup.sh"
cd "$ROOT"
scene=${1:-runs/demo.nml}
shift || true
name=$(basename "$scene" .nml)
out="runs/out/$name"
"$VENV/bin/pyorch" run "$scene" --out "$out" --overwrite "$@"
# the movie, when the scene wrote particle frames (text .dat or binary .bin)
if compgen -G "$out/particles.[db][ai][tn]" >/dev/null || compgen -G "$out/frames.[db][ai][tn]" >/dev/null; then
  "$VENV/bin/pyorch" movie "$out" --out "$out/plots/movie.mp4"
fi
