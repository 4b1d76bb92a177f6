#!/usr/bin/env bash
# The README's main job. Installs what it needs, builds, then runs the pipeline on a
# default scenario and prints the accuracy. Until `waymark demo` exists (localization
# issue) this is: simulate the corridor survey, then evaluate dead reckoning against
# ground truth — the baseline every later stage must beat.
# Usage: scripts/demo.sh [OUT_DIR]   (default: out/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
out=${1:-out/demo}
rm -rf "$out"
mkdir -p "$out"
./build/waymark sim corridor --out "$out/corridor" --seed 1
./build/waymark eval --est "$out/corridor/odometry.tum" --gt "$out/corridor/groundtruth/trajectory.tum" \
  --align se2 --json "$out/odometry_eval.json" --report "$out/odometry_eval.md" --plot "$out/odometry_eval.svg"
echo "demo: report in $out/odometry_eval.md, plot in $out/odometry_eval.svg" >&2
