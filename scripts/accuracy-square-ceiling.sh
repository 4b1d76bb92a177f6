#!/usr/bin/env bash
# Issue 16's acceptance run for [Seki] (the square ceiling marker), through the binary, per seed:
#   waymark sim square-ceiling --out D --seed N --render [--set ...]   (rendered LED pairs)
#   waymark detect D --out D/detections.jsonl --families square       (the detector on the images)
#   waymark localize D --map D/markers.json --out run.tum              (tight EKF, the known square)
#   waymark eval --est run.tum --gt D/groundtruth/trajectory.tum --align none
# and prints per seed: the ATE RMSE (mm), the heading (yaw) RMSE and max (deg), a flip (yaw error
# over 45 deg anywhere), the pairs with a detection and the detector's time per pair. The target
# (issue 16): ATE <= 10 mm, heading RMSE <= 0.3 deg, no flip, on seeds 1-20. Extra arguments go to
# `waymark sim` (e.g. --set camera.tilt_deg=0.1 --render-every 2).
# Usage: scripts/accuracy-square-ceiling.sh [BUILD_DIR] [FIRST_SEED] [LAST_SEED] [SIM ARGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build}/waymark
first=${2:-1}
last=${3:-20}
shift $(( $# < 3 ? $# : 3 ))
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

json_after() { sed -n "/\"$2\"/,\$p" "$1" | grep -o "\"$3\": *[-0-9.eE+]*" | head -n 1 | sed 's/.*: *//'; }

echo "| seed | ATE RMSE (mm) | heading RMSE (deg) | heading max (deg) | flip | pairs with the square | detect ms/pair (mean) |"
echo "|---|---|---|---|---|---|---|"
for seed in $(seq "$first" "$last"); do
  d="$work/d$seed"
  "$waymark" sim square-ceiling --out "$d" --seed "$seed" --render "$@" 2>/dev/null
  "$waymark" detect "$d" --out "$d/detections.jsonl" --families square 2>"$work/detect.log"
  "$waymark" localize "$d" --map "$d/markers.json" --out "$work/run.tum" >/dev/null 2>&1
  "$waymark" eval --est "$work/run.tum" --gt "$d/groundtruth/trajectory.tum" --align none --json "$work/eval.json" \
    >/dev/null
  ate=$(json_after "$work/eval.json" ate rmse)
  yaw_rmse=$(json_after "$work/eval.json" yaw_deg rmse)
  yaw_max=$(json_after "$work/eval.json" yaw_deg max)
  pairs=$(grep -c '"square"' "$d/detections.jsonl" || true)
  total=$(wc -l <"$d/detections.jsonl")
  ms=$(sed -n 's/.*mean \([0-9.]*\) ms.*/\1/p' "$work/detect.log")
  flip=$(awk -v m="$yaw_max" 'BEGIN { print (m > 45 ? "yes" : "no") }')
  printf '| %s | %.1f | %.3f | %.3f | %s | %s/%s | %s |\n' "$seed" "$(awk -v a="$ate" 'BEGIN { print a * 1000 }')" \
    "$yaw_rmse" "$yaw_max" "$flip" "$pairs" "$total" "$ms"
  rm -rf "$d"
done
