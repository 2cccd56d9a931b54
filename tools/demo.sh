#!/usr/bin/env bash
# The main job, end to end, on one machine: installs what is missing, builds,
# simulates the `covisible` scenario, then runs ground_server, air_agent (live
# mode) and the dataset player over LCM inside a private network namespace
# (loopback only: nothing leaves this machine) and prints, per air agent, the
# estimated T_wa_wg, the ground truth, the errors (against groundtruth.yaml and
# drift-free), the link bandwidth and the end-to-end latency. Exits non-zero
# when an air agent got no fix.
#
# Environment: AG_DEMO_DIR (work folder, default /tmp/ag_demo), AG_DEMO_SEED
# (default 1), AG_DEMO_DURATION (seconds of the scenario, default: all 60),
# AG_XFEAT_MODEL (the XFeat ONNX file; default ../shared/models/xfeat.onnx,
# else classical features with a warning).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
work=${AG_DEMO_DIR:-/tmp/ag_demo}
seed=${AG_DEMO_SEED:-1}

tools/setup.sh
start=$(date +%s)

if ! unshare -rn true 2>/dev/null; then
  echo "demo: cannot create a private network namespace (unshare -rn): LCM's multicast must" >&2
  echo "demo: stay on this machine, so the demo runs only inside one. Enable unprivileged user" >&2
  echo "demo: namespaces (sysctl kernel.unprivileged_userns_clone=1) or run as root." >&2
  exit 2
fi

if [ -z "${AG_XFEAT_MODEL:-}" ] && [ -f "$root/../shared/models/xfeat.onnx" ]; then
  export AG_XFEAT_MODEL="$root/../shared/models/xfeat.onnx"
fi
if [ -z "${AG_XFEAT_MODEL:-}" ]; then
  echo "demo: WARNING: no XFeat model (set AG_XFEAT_MODEL; see README): classical features," >&2
  echo "demo: WARNING: expect fewer matches and maybe no fix." >&2
fi

rm -rf "$work"
mkdir -p "$work"
dataset="$work/covisible"
sim_args=(--scenario config/scenarios/covisible.yaml --seed "$seed" --out "$dataset")
if [ -n "${AG_DEMO_DURATION:-}" ]; then sim_args+=(--duration "$AG_DEMO_DURATION"); fi
echo "demo: simulating the covisible scenario (seed $seed) into $dataset"
build/tools/sim/simulate "${sim_args[@]}" > "$work/simulate.log" 2>&1 ||
  { cat "$work/simulate.log" >&2; exit 1; }
simulated=$(date +%s)
echo "demo: simulated in $((simulated - start)) s; running the daemons in a private network namespace"

agents=$(ls "$dataset/air")
export AG_DEMO_ROOT="$root" AG_DEMO_WORK="$work" AG_DEMO_DATASET="$dataset" AG_DEMO_AGENTS="$agents"
status=0
unshare -rn bash -c '
  set -u
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  url="udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
  b="$AG_DEMO_ROOT/build"
  ds="$AG_DEMO_DATASET"
  pids=()
  "$b/ground_server/server/ground_server" --lcm-url "$url" \
      --calibration "$ds/ground/calibration.yaml" \
      --persistence-dir "$AG_DEMO_WORK/ground_state" > "$AG_DEMO_WORK/ground_server.log" 2>&1 &
  pids+=($!)
  for a in $AG_DEMO_AGENTS; do
    "$b/air_agent/agent/air_agent" --lcm-url "$url" --agent "$a" \
        --calibration "$ds/air/$a/calibration.yaml" > "$AG_DEMO_WORK/air_agent_$a.log" 2>&1 &
    pids+=($!)
  done
  "$b/tools/monitor/relative_pose_monitor" --lcm-url "$url" --dataset "$ds" --require-fix \
      --jsonl "$AG_DEMO_WORK/relative_poses.jsonl" > "$AG_DEMO_WORK/monitor.log" 2>&1 &
  monitor=$!
  sleep 2  # let the daemons subscribe
  "$b/tools/player/play_dataset" --lcm-url "$url" --dataset "$ds" --speed 1 \
      > "$AG_DEMO_WORK/play_dataset.log" 2>&1
  sleep 4  # the last keyframes reach the estimator
  kill -TERM "$monitor"
  wait "$monitor"
  result=$?
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  for p in "${pids[@]}"; do wait "$p" || true; done
  exit $result
' || status=$?
end=$(date +%s)

grep -E "^(==| )" "$work/monitor.log" || true
echo
echo "demo: fixes over time: $work/relative_poses.jsonl; logs: $work/*.log"
# Each daemon's last line: its CPU time and peak memory over the run.
usage() { grep -o "stopped.*CPU.*" "$1" | tail -n 1 | sed "s/^stopped[^;]*; //"; }
echo "demo: ground_server: $(usage "$work/ground_server.log")"
for a in $agents; do
  echo "demo: air_agent $a: $(usage "$work/air_agent_$a.log")"
done
echo "demo: simulate $((simulated - start)) s, daemons $((end - simulated)) s (after the build)"
if [ "$status" -ne 0 ]; then
  echo "demo: FAILED: no fix for at least one air agent (see $work/ground_server.log)" >&2
fi
exit "$status"
