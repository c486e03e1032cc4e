#!/usr/bin/env bash
# Tests: same set-up as the main job, then the pytest suite (extra pytest
# arguments are passed through, e.g. -k convergence).
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
source "$ROOT/scripts/setup.sh"
cd "$ROOT"
exec "$VENV/bin/pytest" tests "$@"
