#!/usr/bin/env bash
# Build one variant of Frank Smallenburg's public EDMD (github.com/FSmallenburg/EDMD, MIT
# licence; 3D hard spheres, periodic box) for one benchmark run, beside our engine
# (bench/edmd_vs_peer.py). The peer's code is never copied into this repository: it is
# fetched at a pinned commit (or taken from EDMD_PEER_DIR), copied to the build directory and
# changed there only by the build-time settings below.
#
#   bash bench/edmd_peer/build.sh VARIANT N PACKFRAC MAXTIME OUTDIR     # -> OUTDIR/md
#
#   VARIANT   Cell | Single | Multi
#   N         particles, 4 k^3 (the peer's FCC start: 864, 10976, 97556, 1000188, ...)
#   PACKFRAC  packing fraction of the spheres
#   MAXTIME   simulated time [the peer's tau = sigma sqrt(m / kT)]
#   OUTDIR    build directory (created; the binary is OUTDIR/md)
#
# Environment: EDMD_PEER_DIR (a checkout of the peer; default: clone into
# ${EDMD_PEER_CACHE:-/tmp/edmd_peer} at $PIN), CC (default gcc), CFLAGS (default our engine's
# flags -O3 -march=native; the peer's own Makefiles use -Wall -Ofast -funroll-loops
# -march=native).
#
# What is changed, and why (every change is checked: the build stops if a pattern is absent):
#  1. initialconfig = 1, N, packfrac: start from the peer's own FCC crystal at N and the
#     packing fraction of the run (no input file);
#  2. maxtime: the run length (~100 collisions per particle, set by the driver);
#  3. writeinterval = 2 MAXTIME: output off - the peer writes one status line and one pressure
#     row at t = 0 only (its final snapshot is written after the timed loop; a far larger
#     interval overflows the int bucket index of Single's and Multi's addevent);
#  4. usethermostat = 0 (Single's default is 1): constant energy, like Cell, Multi and ours;
#  5. Cell only: MAXCEL = the number of cells per side the peer's initcelllist asks for at this
#     N (its default 75 would cap the cells at N >~ 1.5e5 and cripple large N; a larger
#     constant would spread the static 3D array celllist[MAXCEL][MAXCEL][MAXCEL] and slow
#     small N: exactly the needed size is neither);
#  6. timing: main's event loop is bracketed by clock_gettime (wall, CLOCK_MONOTONIC; CPU,
#     CLOCK_PROCESS_CPUTIME_ID) and one line goes to stderr:
#       EDMD_PEER_LOOP wall_s=... cpu_s=... collisions=... simtime=...
#     (set-up and the final snapshot excluded, as our run.json event_loop_cpu_seconds).
# Nothing in the event machinery is touched.
set -euo pipefail

PIN=65a9972a57c5d72b61a1dbdeeb4f35259832fca6
URL=https://github.com/FSmallenburg/EDMD

if [ $# -ne 5 ]; then
  sed -n '2,14p' "$0" >&2
  exit 2
fi
VARIANT=$1; N=$2; PACKFRAC=$3; MAXTIME=$4; OUT=$5
case "$VARIANT" in Cell|Single|Multi) ;; *)
  echo "build.sh: VARIANT must be Cell, Single or Multi (got '$VARIANT')" >&2; exit 2;; esac
K=$(awk -v n="$N" 'BEGIN { k = int(exp(log(n / 4) / 3) + 0.5); print (4 * k * k * k == n) ? k : -1 }')
if [ "$K" -lt 1 ]; then
  echo "build.sh: N must be 4 k^3 for the peer's FCC start (got $N)" >&2; exit 2
fi

SRC=${EDMD_PEER_DIR:-}
if [ -z "$SRC" ]; then
  SRC=${EDMD_PEER_CACHE:-/tmp/edmd_peer}
  if [ ! -d "$SRC/.git" ]; then
    git clone --quiet "$URL" "$SRC"
  fi
  git -C "$SRC" checkout --quiet "$PIN"
elif [ -d "$SRC/.git" ]; then
  head=$(git -C "$SRC" rev-parse HEAD)
  [ "$head" = "$PIN" ] || echo "build.sh: warning: $SRC is at $head, not the pinned $PIN" >&2
fi
[ -f "$SRC/$VARIANT/md$VARIANT.c" ] || { echo "build.sh: no $SRC/$VARIANT/md$VARIANT.c" >&2; exit 2; }

mkdir -p "$OUT"
cp "$SRC/$VARIANT/md$VARIANT.c" "$SRC/$VARIANT/md$VARIANT.h" "$OUT/"
# the variants #include "mt19937ar.c" (the Mersenne Twister), kept in the peer's Grow/
if [ -f "$SRC/$VARIANT/mt19937ar.c" ]; then cp "$SRC/$VARIANT/mt19937ar.c" "$OUT/"
else cp "$SRC/Grow/mt19937ar.c" "$OUT/"; fi
F="$OUT/md$VARIANT.c"

# set KEY: replace the line matching regex $1 by $2 (exactly one line must match)
set_line() {
  local n
  n=$(grep -c -E "$1" "$F" || true)
  if [ "$n" -ne 1 ]; then
    echo "build.sh: expected one line matching '$1' in $F, found $n (not the pinned commit?)" >&2
    exit 3
  fi
  sed -i -E "s|$1.*|$2|" "$F"
}

set_line '^int initialconfig = 0;' 'int initialconfig = 1;'
set_line '^int N = [0-9]+;' "int N = $N;"
set_line '^double packfrac = [0-9.]+;' "double packfrac = $PACKFRAC;"
set_line '^double maxtime = [0-9.]+;' "double maxtime = $MAXTIME;"
set_line '^double writeinterval = [0-9.]+;' "double writeinterval = 2 * $MAXTIME;"
set_line '^const int usethermostat = [01];' 'const int usethermostat = 0;'
if [ "$VARIANT" = Cell ]; then
  # the cell count of initcelllist: (int)(L - 0.0001), shrunk by 0.9 while > 8 N cells
  CELLS=$(awk -v n="$N" -v eta="$PACKFRAC" 'BEGIN {
      l = exp(log(n / (6.0 / 3.141592653589793 * eta)) / 3); c = int(l - 0.0001);
      while (c * c * c > 8 * n) c = int(c * 0.9); print c }')
  set_line '^#define MAXCEL [0-9]+' "#define MAXCEL $CELLS"
fi
# timing of main's event loop (stderr), and <time.h>
set_line '^#include <string.h>' '#include <string.h>\n#include <time.h>'
set_line '^    while \(simtime <= maxtime\)' \
  '    struct timespec edmd_w0, edmd_c0, edmd_w1, edmd_c1;\n    clock_gettime(CLOCK_MONOTONIC, \&edmd_w0); clock_gettime(CLOCK_PROCESS_CPUTIME_ID, \&edmd_c0);\n    while (simtime <= maxtime)'
set_line '^    simtime = maxtime;' \
  '    clock_gettime(CLOCK_MONOTONIC, \&edmd_w1); clock_gettime(CLOCK_PROCESS_CPUTIME_ID, \&edmd_c1);\n    fprintf(stderr, "EDMD_PEER_LOOP wall_s=%.6f cpu_s=%.6f collisions=%u simtime=%.6f\\n", (edmd_w1.tv_sec - edmd_w0.tv_sec) + 1e-9 * (edmd_w1.tv_nsec - edmd_w0.tv_nsec), (edmd_c1.tv_sec - edmd_c0.tv_sec) + 1e-9 * (edmd_c1.tv_nsec - edmd_c0.tv_nsec), colcounter, simtime);\n    simtime = maxtime;'

${CC:-gcc} ${CFLAGS:--O3 -march=native} -o "$OUT/md" "$F" -lm
echo "$OUT/md"
