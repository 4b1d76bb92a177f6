#!/usr/bin/env bash
# Online localization on the real TagSLAM sets (../shared/data/tagslam) for docs/accuracy.md:
# for each set, `waymark localize` against TagSLAM's own map (reference/markers.json), in the
# default tight mode (with the set's odometry when it has one, else the random walk and the
# frame fit of online/localizer.h) and in --mode single-frame (each camera frame's robust PnP on
# its own, the baseline), each compared with TagSLAM's trajectory (`waymark eval --align none`:
# the same map, so the same frame). Prints a Markdown table: camera instants with a mapped code,
# poses output at them, times lost and restarts, the ATE RMSE / median / max of both modes and,
# for a set with odometry, the odometry's own ATE (aligned to TagSLAM's trajectory with SE(3):
# the best it could do).
# Usage: scripts/online-tagslam.sh [BUILD_DIR] [SET...]   (default: build, all six sets)
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build}/waymark
shift || true
sets=("$@")
[ ${#sets[@]} -eq 0 ] && sets=(tagslam-test16 tagslam-test17 tagslam-test22 tagslam-test13 tagslam-test10-priors
                              tagslam-test6)
data=../shared/data/tagslam
if [ ! -d "$data" ]; then
  echo "online-tagslam: $data is absent (the shared data folder); nothing to measure" >&2
  exit 1
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# "rmse / median / max" (mm) of the ATE: the keys of the "ate" object of waymark eval's JSON
# before its "rotation_deg" (rmse, mean, median, std, min, max, ...), at full precision.
ate_mm() {
  "$waymark" eval --est "$1" --gt "$2" --align "$3" --json "$work/eval.json" > /dev/null
  tr -d '\n ' < "$work/eval.json" | sed 's/.*"ate":{//; s/"rotation_deg".*//' | tr ',' '\n' |
    awk -F: '{v[$1] = $2} END {printf "%.2f / %.2f / %.1f", v["\"rmse\""] * 1e3, v["\"median\""] * 1e3, v["\"max\""] * 1e3}'
}

echo "| set | odometry | instants with a mapped code | tight: poses there, lost, restarts | tight: ATE RMSE / median / max (mm) | single-frame: poses there | single-frame: ATE (mm) | odometry alone: ATE (mm, SE(3)-aligned) |"
echo "|---|---|---|---|---|---|---|---|"
for name in "${sets[@]}"; do
  set_dir=$data/$name
  ref=$set_dir/reference/trajectory.tum
  for mode in tight single-frame; do
    "$waymark" localize "$set_dir" --map "$set_dir/reference/markers.json" --out "$work/$mode.tum" \
      --mode "$mode" > "$work/$mode.txt"
  done
  # Instants (stamps, to 0.1 ms) with a code (every code of these sets is in TagSLAM's map), and
  # how many of them have a pose in a TUM file.
  grep -v '"markers": \[\]' "$set_dir/detections.jsonl" | sed 's/^{"t": *\([0-9.e+-]*\),.*/\1/' |
    awk '{printf "%.4f\n", $1}' | sort -u > "$work/instants.txt"
  posed() { grep -v '^#' "$1" | awk '{printf "%.4f\n", $1}' | sort -u | comm -12 - "$work/instants.txt" | wc -l; }
  lost=$(sed -n 's/^initializations: \([0-9]*\) (relocalizations \([0-9]*\)), times lost \([0-9]*\).*/\3, \2/p' "$work/tight.txt")
  odometry="none"
  odometry_ate="—"
  if [ -f "$set_dir/odometry.tum" ]; then
    odometry="yes"
    odometry_ate=$(ate_mm "$set_dir/odometry.tum" "$ref" se3)
  fi
  printf '| %s | %s | %s | %s, %s | %s | %s | %s | %s |\n' "$name" "$odometry" "$(wc -l < "$work/instants.txt")" \
    "$(posed "$work/tight.tum")" "$lost" "$(ate_mm "$work/tight.tum" "$ref" none)" \
    "$(posed "$work/single-frame.tum")" "$(ate_mm "$work/single-frame.tum" "$ref" none)" "$odometry_ate"
done
