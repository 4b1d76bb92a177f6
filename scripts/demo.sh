#!/usr/bin/env bash
# The README's main job. Installs what it needs, builds, then runs the pipeline on the
# corridor scenario (seed 000's setting) and prints the accuracy:
#   simulate a survey -> evaluate dead reckoning -> learn the map (Ceres) -> evaluate the map
#   and the smoothed trajectory against ground truth.
# Online localization (`waymark localize`, `waymark demo`) joins when it lands.
# Usage: scripts/demo.sh [OUT_DIR]   (default: out/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
waymark=./build/waymark
out=${1:-out/demo}
rm -rf "$out"
mkdir -p "$out"
survey="$out/corridor-survey"
gt="$survey/groundtruth"

"$waymark" sim corridor --out "$survey" --seed 1
echo "== odometry alone (dead reckoning from the known start pose)"
"$waymark" eval --est "$survey/odometry.tum" --gt "$gt/trajectory.tum" --align origin \
  --json "$out/odometry_eval.json" --report "$out/odometry_eval.md" --plot "$out/odometry_eval.svg"
"$waymark" map build "$survey" --out "$out/map.json" --trajectory "$out/smoothed.tum"
echo "== learned map against the true marker poses"
"$waymark" eval --map "$out/map.json" --gt-map "$gt/markers.json" --json "$out/map_eval.json" \
  --report "$out/map_eval.md"
echo "== smoothed survey trajectory"
"$waymark" eval --est "$out/smoothed.tum" --gt "$gt/trajectory.tum" --align origin \
  --json "$out/smoothed_eval.json" --report "$out/smoothed_eval.md" --plot "$out/smoothed_eval.svg" \
  --markers "$out/map.json" --gt-map "$gt/markers.json"
echo "demo: reports and plots in $out/" >&2
