#!/usr/bin/env bash
# Same bytes from two engine builds: every output file, the checkpoint (but for its
# wall time, run id and payload CRC) and run.json (but for the run id, wall times,
# CPU seconds) of short runs of every kind, run to the end and paused + resumed.
#   bash scripts/compare_builds.sh OLD_PARTSIM NEW_PARTSIM [WORKDIR]
# Runs: tiny scenes of every kind with every output on (text and binary frames), each
# complete and paused at a step then resumed to the end (the Lennard-Jones law also by each
# pair evaluation, its linear core reached; the bed's list kernels on the N 2000 grid scene at
# r_c 3, 7, 10); every runs/*.nml paused after
# 40 units and resumed to 80 (COMPARE_ONLY=1: compare the runs already in WORKDIR). Exit 0 when every file matches, 1 otherwise (the
# differing files are listed).
set -euo pipefail
OLD=$(realpath "$1"); NEW=$(realpath "$2")
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
WORK=${3:-$(mktemp -d)}
mkdir -p "$WORK/scenes"
S=$WORK/scenes

cat > "$S/osc.nml" <<'EOF'
&scene kind = 'oscillator' /
&oscillator n = 5, omega = 6.0, zeta = 0.1, dt = 0.01, t_end = 0.5, integrator = 'euler' /
&output trajectory_every = 5, energy_every = 3, checkpoint_every = 10 /
EOF
cat > "$S/rods.nml" <<'EOF'
&scene kind = 'rods' /
&rods n = 500, dt = 0.05, t_end = 1.0, seed = 2 /
&collisions tau = 0.5, e_v = 0.9 /
&mean_field potential = 'onsager', alpha = 0.3, onsager_force = 'fourier' /
&output history_every = 2, histogram_every = 5, samples_every = 10, bins = 10,
  checkpoint_every = 7, collision_audit = .true. /
EOF
cat > "$S/dla.nml" <<'EOF'
&scene kind = 'dla' /
&box lx = 20.0, ly = 20.0 /
&disks count = 60, radius = 0.5, seed = 3 /
&run tick = 0.1, t_end = 6.0 /
&output frame_every = 5, history_every = 2, check_every = 1, checkpoint_every = 13,
  log_events = .true., frames_format = 'both' /
EOF
cat > "$S/lj.nml" <<'EOF'
&scene kind = 'lj_box' /
&box l = 20.0 /
&particles n = 30, min_distance = 2.2, velocities = 'maxwell', temperature = 0.5 /
&physics alpha = 0.02 /
&field type = 'travelling_wave', amplitude = 0.5, ex = 1.0, kx = 0.3, omega = 0.5 /
&integration method = 'velocity_verlet', dt = 1.0e-3, steps = 300 /
&output frame_every = 20, energy_every = 10, field_grid = 4, frames_format = 'both',
  checkpoint_every = 70 /
EOF
# the Lennard-Jones law by every evaluation through the Verlet list (rows_pairs), hot enough
# that pairs come inside r_m (the linear core), p = 6 and 12
for ev in exact single rsqrt table; do
  for p in 6 12; do
    [ $p = 12 ] && [ $ev = single -o $ev = rsqrt ] && continue
    cat > "$S/lj_${ev}_p$p.nml" <<EOF
&scene kind = 'lj_box' /
&box l = 40.0 /
&particles n = 200, min_distance = 2.2, velocities = 'maxwell', temperature = 2.0, seed = 4 /
&physics alpha = 0.0 /
&field type = 'none' /
&steric p = $p, r_m = 1.95, r_cut = 5.0, neighbour = 'verlet', skin = 0.6, pair_eval = '$ev' /
&integration method = 'velocity_verlet', dt = 1.0e-3, steps = 400 /
&output frame_every = 50, energy_every = 5, checkpoint_every = 90 /
EOF
  done
done
# the bed: the demo scene, a short stroke (1 D1 after 2 T of relaxation), every output on,
# both frame formats
sed -e "s/^  frame_every = 5000/  frame_every = 100\n  energy_every = 50\n  frames_format = 'both'\n  checkpoint_every = 150/" \
    -e 's/^  distance_every = 1000/  distance_every = 40/' -e 's/^  t_relax = 60.0 /  t_relax = 2.0 /' \
    -e 's/^  hf = 20.0 /  hf = 74.0 /' -e 's/^  t_final = 10.0 /  t_final = 1.0 /' \
    "$ROOT/runs/demo.nml" > "$S/bed.nml"
grep -q "t_relax = 2.0" "$S/bed.nml" && grep -q "hf = 74.0" "$S/bed.nml"
grep -q "frames_format = 'both'" "$S/bed.nml"
# the bed's list kernels (bench/lammps_compare.py's grid scene at N 2000): rows_kept at r_c 3
# and 7 (with the friction sums at 3), the ranges at r_c 10, rows_list at r_c 10 in single
for rc_ev in 3:exact:first_order 7:exact:none 10:exact:none 10:single:none; do
  IFS=: read -r rc ev fr <<< "$rc_ev"
  cat > "$S/grid_${rc}_${ev}.nml" <<EOF
&scene kind = 'magnet_bed', title = 'list kernels' /
&material density = 7368.0, diameter = 0.006, gap = 0.0031, gravity_si = 9.8, remanence = 1.3,
  thickness = 0.003 /
&cell height = 74.0, width = 74.0 /
&particles fill_height = -1.0, jitter = 0.1, n = 2000, n_species = 1, placement = 'interleave',
  seed = 1, speed_init = 0.01 /
&physics dry_friction = '$fr', gravity = .false., min_distance = 0.5, pair_law = 'dipole',
  wall_law = 'experimental' /
&integration dt = 0.001, integrator = 'velocity_verlet', neighbour = 'verlet', pair_eval = '$ev',
  r_cut = $rc, skin = 1.0, tail = 'none' /
&protocol expand = .true., h_start = 74.0, piston = 'fixed', t_end = 0.3 /
&output checkpoint_every = 100, frame_every = 50, energy_every = 25 /
EOF
done

fail=0 fail_ckpt=0
ckpt_diffs=()
# compare run directories $1 (old) and $2 (new)
compare() {
  local a=$1 b=$2 f name
  for f in "$a"/* "$a"/.outputs; do
    name=$(basename "$f")
    [ -e "$b/$name" ] || { echo "DIFF $b/$name missing"; fail=1; continue; }
    case $name in
      run.json)
        python3 - "$f" "$b/$name" <<'EOF' || fail=1
import json, sys
vol = {"run_id", "wall_time_s", "wall_time_per_step_s", "event_loop_cpu_seconds",
       "pruned_list"}   # pruned_list: the automatic margin follows the run's own timing
a, b = (json.load(open(p)) for p in sys.argv[1:3])
a["scene"] = a["scene"].replace("/old/", "/new/")   # a resumed run names its own scene.nml
a = {k: v for k, v in a.items() if k not in vol}
b = {k: v for k, v in b.items() if k not in vol}
if a != b:
    print("DIFF", sys.argv[2], {k for k in a.keys() | b.keys() if a.get(k) != b.get(k)})
    sys.exit(1)
EOF
        ;;
      checkpoint*.bin)   # header but its payload CRC (0-79), payload after wall, done, run id (120-)
        cmp -s -n 80 "$f" "$b/$name" && cmp -s -i 120 "$f" "$b/$name" \
          || { echo "DIFF $b/$name"; ckpt_diffs+=("$b/$name"); fail_ckpt=$((fail_ckpt + 1)); } ;;
      *) cmp -s "$f" "$b/$name" || { echo "DIFF $b/$name"; fail=1; } ;;
    esac
  done
  [ "$(ls -A "$a" | sort)" = "$(ls -A "$b" | sort)" ] || { echo "DIFF file lists $a $b"; fail=1; }
}
# run scene $1 as label $2 with both builds: complete, and paused at $3 then resumed
run_both() {
  local scene=$1 label=$2 pause=$3 exe tag
  for tag in old new; do
    [ -n "${COMPARE_ONLY:-}" ] && break
    exe=$OLD; [ $tag = new ] && exe=$NEW
    (cd "$WORK" && "$exe" "$scene" --out "$WORK/$tag/$label" --overwrite > "$WORK/$tag/$label.out")
    (cd "$WORK" && "$exe" "$scene" --out "$WORK/$tag/$label.r" --overwrite --stop-at "$pause" \
      > "$WORK/$tag/$label.r.out" && "$exe" --resume "$WORK/$tag/$label.r" >> "$WORK/$tag/$label.r.out")
  done
  compare "$WORK/old/$label" "$WORK/new/$label"
  compare "$WORK/old/$label.r" "$WORK/new/$label.r"
  cmp -s "$WORK/old/$label.out" "$WORK/new/$label.out" || { echo "DIFF stdout $label"; fail=1; }
  cmp -s "$WORK/old/$label.r.out" "$WORK/new/$label.r.out" || { echo "DIFF stdout $label.r"; fail=1; }
  echo "compared $label: $(ls -A "$WORK/new/$label" | tr '\n' ' ')"
}
mkdir -p "$WORK/old" "$WORK/new" "$WORK/old2"
run_both "$S/osc.nml" osc 23
run_both "$S/rods.nml" rods 9
run_both "$S/dla.nml" dla 17
run_both "$S/lj.nml" lj 131
for f in "$S"/lj_*_p*.nml; do
  run_both "$f" "$(basename "$f" .nml)" 170
done
run_both "$S/bed.nml" bed 260
for f in "$S"/grid_*.nml; do
  run_both "$f" "$(basename "$f" .nml)" 130
done
# every shipped top-level scene: paused after 40 units, resumed to 80
for scene in "$ROOT"/runs/*.nml; do
  label=shipped_$(basename "$scene" .nml)
  for tag in old new; do
    [ -n "${COMPARE_ONLY:-}" ] && break
    exe=$OLD; [ $tag = new ] && exe=$NEW
    (cd "$WORK" && "$exe" "$scene" --out "$WORK/$tag/$label" --overwrite --stop-at 40 -q \
      && "$exe" --resume "$WORK/$tag/$label" --stop-at 80 -q)
  done
  compare "$WORK/old/$label" "$WORK/new/$label"
  echo "compared $label: $(ls -A "$WORK/new/$label" | tr '\n' ' ')"
done
# a checkpoint that differs: is it the same in two runs of the old build? (the bed's Verlet
# list is saved with its whole capacity, whose unused tail is not initialised)
for f in $(printf '%s\n' "${ckpt_diffs[@]}"); do
  label=$(basename "$(dirname "$f")")
  scene=$ROOT/runs/${label#shipped_}.nml
  [ -e "$scene" ] || continue
  (cd "$WORK" && "$OLD" "$scene" --out "$WORK/old2/$label" --overwrite --stop-at 40 -q \
    && "$OLD" --resume "$WORK/old2/$label" --stop-at 80 -q)
  if cmp -s -n 80 "$WORK/old/$label/checkpoint.bin" "$WORK/old2/$label/checkpoint.bin" && \
     cmp -s -i 120 "$WORK/old/$label/checkpoint.bin" "$WORK/old2/$label/checkpoint.bin"; then
    echo "  $label: the old build's checkpoint is reproducible: a real difference"
  else
    echo "  $label: two runs of the old build differ there too ($(cmp -l "$WORK/old/$label/checkpoint.bin" \
      "$WORK/old2/$label/checkpoint.bin" | awk '$1 > 120' | wc -l) bytes): not counted"
    fail_ckpt=$((fail_ckpt - 1))
  fi
done
[ $fail_ckpt -gt 0 ] && fail=1
if [ $fail = 0 ]; then
  echo "SAME: every file of every run ($WORK; checkpoints not reproducible by the old build itself: ${#ckpt_diffs[@]})"
else
  echo "DIFFERENT ($WORK)"
fi
exit $fail
