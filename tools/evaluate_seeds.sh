#!/usr/bin/env bash
# Runs the offline evaluator over N seeds of a scenario preset, for one or
# more configurations, and prints the success rate (SR) and error statistics
# per configuration (the paper's Table I layout), then a row per seed saying
# why a failed run failed (tools/evaluation/summarize_seeds.py).
#
#   tools/evaluate_seeds.sh covisible 10
#   tools/evaluate_seeds.sh no_initial_covisibility 10 --ablation
#   tools/evaluate_seeds.sh covisible 5 --keypoints        # 128/256/512/1024
#   AG_SEEDS_DIR=/data/seeds tools/evaluate_seeds.sh covisible 10 -- --encoding int8
#
# --ablation: {consistency only}, {+ air-ground reprojection}, {+ stage 1}.
# Arguments after -- go to every evaluate run. Datasets and reports are kept
# in $AG_SEEDS_DIR (default /tmp/ag_seeds/<preset>); existing datasets are
# reused. Needs a build (tools/setup.sh) and, for XFeat, AG_XFEAT_MODEL.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -lt 2 ]; then
  sed -n '2,15p' "$0"
  exit 2
fi
preset=$1
n=$2
shift 2
mode=full
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --ablation) mode=ablation ;;
    --keypoints) mode=keypoints ;;
    --) shift; extra=("$@"); break ;;
    *) echo "evaluate_seeds: unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
scenario=config/scenarios/$preset.yaml
[ -f "$scenario" ] || { echo "evaluate_seeds: no preset $scenario" >&2; exit 2; }
if [ -z "${AG_XFEAT_MODEL:-}" ] && [ -f ../shared/models/xfeat.onnx ]; then
  export AG_XFEAT_MODEL=$(cd ../shared/models && pwd)/xfeat.onnx
fi
dir=${AG_SEEDS_DIR:-/tmp/ag_seeds/$preset}
mkdir -p "$dir"

case $mode in
  full) variants=("full|") ;;
  ablation)
    variants=("consistency_only|--no-stage1 --no-reprojection"
              "plus_reprojection|--no-stage1"
              "plus_stage1|") ;;
  keypoints)
    variants=("kp128|--keypoints 128" "kp256|--keypoints 256" "kp512|--keypoints 512"
              "kp1024|--keypoints 1024") ;;
esac

for seed in $(seq 1 "$n"); do
  ds="$dir/seed$seed"
  if [ ! -f "$ds/dataset.yaml" ]; then
    echo "evaluate_seeds: simulating $preset seed $seed"
    build/tools/sim/simulate --scenario "$scenario" --seed "$seed" --out "$ds" > "$dir/simulate_$seed.log" 2>&1
  fi
  for v in "${variants[@]}"; do
    name=${v%%|*}
    # shellcheck disable=SC2206
    args=(${v#*|})
    out="$dir/$name/seed$seed"
    if [ ! -f "$out/report.json" ]; then
      echo "evaluate_seeds: $name seed $seed"
      build/tools/evaluation/evaluate --dataset "$ds" --out "$out" --no-plots "${args[@]}" \
          "${extra[@]}" > "$dir/evaluate_${name}_$seed.log" 2>&1 || true
    fi
  done
done

tools/evaluation/summarize_seeds.py "$dir" "$n" "${variants[@]}"
