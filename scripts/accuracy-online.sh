#!/usr/bin/env bash
# [Bach]'s Table 1 end to end through the binary (the in-process twin, with Monte-Carlo runs,
# is bench/online_accuracy_bench.cc). For each code spacing d = 1, 2, 4 m on sim `corridor`:
#   survey (seed SEED + 1000) -> waymark map build -> map.json (with its covariance)
#   run    (seed SEED)        -> odometry alone, waymark localize --mode loose / tight,
#                                waymark map build --trajectory (offline smoothing of the run)
#   -> waymark eval: PE and TE ([Bach], eq. 15) and the ATE against the run's ground truth.
# PE/TE: the pose just before each correction (`localize --predicted`) for the filters; for
# odometry (first pose on the truth: --align origin) and smoothing, the pose at the camera
# instants that saw a code. Filters and smoothing are not aligned: the map's anchors define the
# world frame. Prints a Markdown table.
# Usage: scripts/accuracy-online.sh [BUILD_DIR] [SEED]     (defaults: build, 1)
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build}/waymark
seed=${2:-1}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# First number after a key in a JSON file, after the first occurrence of section $2.
json_after() { sed -n "/\"$2\"/,\$p" "$1" | grep -o "\"$3\": *[-0-9.eE+]*" | head -n 1 | sed 's/.*: *//'; }

# The poses of TUM file $1 at the stamps of the frames of $2/detections.jsonl that saw a code.
at_detections() {
  grep -v '"markers": *\[ *\]' "$2/detections.jsonl" | sed -n 's/.*"t": *\([-0-9.eE+]*\).*/\1/p' >"$work/stamps"
  awk 'NR == FNR { s[sprintf("%.6f", $1)] = 1; next } /^#/ { next } (sprintf("%.6f", $1) in s)' \
    "$work/stamps" "$1"
}

# row D METHOD EST [PREDICTED] [ALIGN]: one table row from waymark eval.
row() {
  local d=$1 method=$2 est=$3 predicted=$4 align=$5 json="$work/eval.json"
  local extra=()
  [[ $align == origin ]] && extra=(--align-predicted)
  "$waymark" eval --est "$est" --gt "$work/run-d$d/groundtruth/trajectory.tum" --align "$align" \
    --predicted "$predicted" "${extra[@]}" --json "$json" >/dev/null
  printf '| %s | %s | %.4f | %.3f | %.4f | %.4f |\n' "$d" "$method" "$(json_after "$json" pe_m mean)" \
    "$(json_after "$json" te_deg mean)" "$(json_after "$json" ate rmse)" "$(json_after "$json" ate mean)"
}

echo "| d (m) | method (seed $seed, map from seed $((seed + 1000))'s survey) | PE (m) | TE (deg) | ATE RMSE (m) | ATE mean (m) |"
echo "|---|---|---|---|---|---|"
for d in 1 2 4; do
  run="$work/run-d$d" survey="$work/survey-d$d"
  "$waymark" sim corridor --spacing "$d" --seed "$seed" --out "$run" 2>/dev/null
  "$waymark" sim corridor --spacing "$d" --seed $((seed + 1000)) --out "$survey" 2>/dev/null
  "$waymark" map build "$survey" --out "$work/map-d$d.json" >/dev/null 2>&1
  "$waymark" map build "$run" --out "$work/run-map-d$d.json" --trajectory "$work/smoothed-d$d.tum" >/dev/null 2>&1
  at_detections "$run/odometry.tum" "$run" >"$work/odometry-at-codes.tum"
  row "$d" odometry "$run/odometry.tum" "$work/odometry-at-codes.tum" origin
  for mode in loose tight; do
    "$waymark" localize "$run" --map "$work/map-d$d.json" --mode "$mode" --out "$work/$mode.tum" \
      --predicted "$work/$mode-predicted.tum" >/dev/null 2>&1
    label=$([[ $mode == loose ]] && echo "loose ([Bach])" || echo "ours (tight)")
    row "$d" "$label" "$work/$mode.tum" "$work/$mode-predicted.tum" none
  done
  at_detections "$work/smoothed-d$d.tum" "$run" >"$work/smoothed-at-codes.tum"
  row "$d" "smoothing (offline)" "$work/smoothed-d$d.tum" "$work/smoothed-at-codes.tum" none
done
