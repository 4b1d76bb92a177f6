#!/usr/bin/env bash
# Dead-reckoning baseline for docs/accuracy.md: for each built-in scenario, simulate a run and
# evaluate its odometry against ground truth with `waymark eval`, printing a Markdown table.
# The simulator's odometry starts at identity, so "--align origin" puts its first pose on the
# true start: what a robot started at a known pose would see (dead reckoning). "aligned" removes
# the best rigid motion (SE(2) for planar robots, SE(3) for the drone) as evo_ape -a does.
# Usage: scripts/accuracy-odometry.sh [BUILD_DIR] [SEED]     (defaults: build, 1)
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build}/waymark
seed=${2:-1}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# First number after a key in waymark eval's JSON (the first "rmse" is the ATE translation RMSE).
json_number() { grep -o "\"$2\": *[-0-9.eE+]*" "$1" | head -n 1 | sed 's/.*: *//'; }

row() {  # name scenario align [sim args...]
  local name=$1 scenario=$2 align=$3
  shift 3
  "$waymark" sim "$scenario" --out "$work/$name" --seed "$seed" "$@" 2>/dev/null
  local gt="$work/$name/groundtruth/trajectory.tum" est="$work/$name/odometry.tum"
  "$waymark" eval --est "$est" --gt "$gt" --align origin --json "$work/$name.none.json" >/dev/null
  "$waymark" eval --est "$est" --gt "$gt" --align "$align" --json "$work/$name.aligned.json" >/dev/null
  local path_m
  path_m=$("$waymark" dataset info "$work/$name" | sed -n 's/^odometry:.*path \([0-9.]*\) m.*/\1/p')
  printf '| %s | %s | %.3f | %.3f | %.3f | %.2f | %s: %.3f |\n' "$name" "$path_m" \
    "$(json_number "$work/$name.none.json" rmse)" "$(json_number "$work/$name.none.json" mean)" \
    "$(json_number "$work/$name.none.json" max)" \
    "$(grep -A2 '"rotation_deg"' "$work/$name.none.json" | json_number /dev/stdin rmse)" \
    "$align" "$(json_number "$work/$name.aligned.json" rmse)"
}

echo "| scenario (seed $seed) | path (m) | ATE RMSE (m) | mean (m) | max (m) | heading RMSE (deg) | aligned ATE RMSE (m) |"
echo "|---|---|---|---|---|---|---|"
row corridor-d1 corridor se2 --spacing 1
row corridor-d2 corridor se2 --spacing 2
row corridor-d4 corridor se2 --spacing 4
row ceiling-grid ceiling-grid se2
row rooms rooms se2
row warehouse-drone warehouse-drone se3
