#!/bin/bash
# interleaved: fixed margins x r_c at N 2e3, 10000 steps; user CPU s. g2e3_10k.nml: the scene of
# bench/ab_engines.py grid_scenes("2000:3", "exact") with protocol t_end = 10 (10 000 steps)
E=${PARTSIM:-.venv/bin/partsim}   # run from a directory holding g2e3_10k.nml
for rep in 1 2 3 4 5; do
 for rc in 3.0 4.0; do
  for ps in 0.05 0.1 0.15 0.25 0.4; do
   sed "s/r_cut = 3.0/r_cut = $rc/; s/prune_skin = -1.0/prune_skin = $ps/" g2e3_10k.nml > q_${rc}_${ps}.nml
   t=$( { /usr/bin/time -f "%U" env OMP_NUM_THREADS=1 $E q_${rc}_${ps}.nml --out /tmp/margin_cal_out --overwrite --quiet; } 2>&1 )
   pr=$(grep -o '"prunes": [0-9]*, "pairs": [0-9]*' /tmp/margin_cal_out/run.json)
   echo "$rep $rc $ps $t $pr"
  done
 done
done
