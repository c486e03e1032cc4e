#!/usr/bin/env bash
# Train (or roll out) geoelements/gns on a pyorch GNS dataset; the recipe: examples/gns/README.md.
#
#   examples/gns/train_gns.sh GNS_CHECKOUT DATASET_DIR [STEPS] [hydra overrides ...]
#
# GNS_CHECKOUT: a clone of geoelements/gns (its config.yaml is the base config); DATASET_DIR: a
# directory written by `pyorch dataset gns` (metadata.json, train/valid/test.npz, dataset.json).
# Runs `python -m gns.train` in the checkout with this directory's torch_cluster stand-in on
# PYTHONPATH, data.path = 'DATASET_DIR/' (quoted for hydra; gns appends file names), data.noise_std =
# dataset.json's noise.suggested_noise_std, training.steps = STEPS (default 2000), and models,
# rollouts and logs in $GNS_OUT (default DATASET_DIR/gns/). Further hydra overrides pass through,
# and win: e.g. `mode=rollout model.file=model-2000.pt`, `data.noise_std=6.7e-4`.
# $PYTHON: the interpreter of the environment that has torch (default python3).
set -euo pipefail

if [[ $# -lt 2 ]]; then
    sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
fi
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
gns_dir=$(cd "$1" && pwd)
data=$(cd "$2" && pwd)
steps=${3:-2000}
shift $(( $# < 3 ? $# : 3 ))
python=${PYTHON:-python3}
out=${GNS_OUT:-$data/gns}

for f in metadata.json train.npz dataset.json; do
    if [[ ! -f "$data/$f" ]]; then
        echo "train_gns.sh: $data/$f missing: DATASET_DIR must be a pyorch GNS dataset" >&2
        exit 2
    fi
done
if [[ ! -f "$gns_dir/gns/train.py" || ! -f "$gns_dir/config.yaml" ]]; then
    echo "train_gns.sh: $gns_dir has no gns/train.py and config.yaml: not a geoelements/gns checkout" >&2
    exit 2
fi
if ! [[ "$steps" =~ ^[1-9][0-9]*$ ]]; then
    echo "train_gns.sh: STEPS = '$steps': expected an integer >= 1" >&2
    exit 2
fi
noise=$("$python" -c 'import json, sys
try:
    print(float(json.load(open(sys.argv[1]))["noise"]["suggested_noise_std"]))
except (OSError, ValueError, KeyError, TypeError):
    sys.exit(1)' "$data/dataset.json") || {
    echo "train_gns.sh: $data/dataset.json has no noise.suggested_noise_std (written by pyorch >= issue 26)" >&2
    exit 2
}
case "$data$out" in
    *"'"*) echo "train_gns.sh: a path with a single quote cannot be passed to hydra: $data, $out" >&2
           exit 2 ;;
esac
mkdir -p "$out"
cd "$gns_dir"
export PYTHONPATH="$here/shim${PYTHONPATH:+:$PYTHONPATH}"
exec "$python" -m gns.train --config-path "$gns_dir" --config-name config.yaml \
    mode=train "data.path='$data/'" data.noise_std="$noise" training.steps="$steps" \
    "model.path='$out/models/'" "output.path='$out/rollouts/'" \
    "logging.tensorboard_dir='$out/logs/'" \
    "$@"
