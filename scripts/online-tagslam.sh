#!/usr/bin/env bash
# Online localization on the real TagSLAM sets (../shared/data/tagslam) for docs/accuracy.md:
# for each set, `waymark localize` against two maps, TagSLAM's own (reference/markers.json) and
# the one `waymark map build` makes from the set itself, in the default tight mode (with the
# set's odometry when it has one, else the random walk and the frame fit of online/localizer.h)
# and in --mode single-frame (each camera frame's robust PnP on its own, the baseline), each
# compared with TagSLAM's trajectory (`waymark eval --align none`: every set holds a tag of known
# pose, so both maps are in TagSLAM's frame). Prints a Markdown table: camera instants with a
# mapped code, poses output at them, times lost and restarts, the ATE RMSE / median / max of both
# modes and, for a set with odometry, the odometry's own ATE (aligned to TagSLAM's trajectory
# with SE(3): the best it could do).
#
# A set with odometry is localized with the odometry time offset its map build estimated (the
# build's note "time offset estimated at S s ... applied"; --odometry-time-offset). The odometry
# of tagslam-test22 is a RealSense T265's visual-inertial odometry, and its dataset.yaml states no
# noise model (the default is a wheel odometry's 2 % per metre): it is localized through a copy
# of the set whose dataset.yaml states the VIO model below (docs/mapping.md, "Odometry noise
# models"), as a user of that camera would state it.
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
# Visual-inertial odometry (T265): 2 % per metre and per radian per sample, and a random walk of
# 2 cm and 0.01 rad per sqrt(s) (hand-held, 4 Hz samples whose stamps jitter: the map build's
# links between frames disagree with the smoothed trajectory by about 1 cm and 0.005 rad over
# 0.25 s, docs/mapping.md "Real data").
vio_sigma="odometry_sigma: {trans_per_m: 0.02, rot_per_rad: 0.02, trans_per_sqrt_s: 0.02, rot_per_sqrt_s: 0.01}"

# "rmse / median / max" (mm) of the ATE: the keys of the "ate" object of waymark eval's JSON
# before its "rotation_deg" (rmse, mean, median, std, min, max, ...), at full precision.
ate_mm() {
  "$waymark" eval --est "$1" --gt "$2" --align "$3" --json "$work/eval.json" > /dev/null
  tr -d '\n ' < "$work/eval.json" | sed 's/.*"ate":{//; s/"rotation_deg".*//' | tr ',' '\n' |
    awk -F: '{v[$1] = $2} END {printf "%.2f / %.2f / %.1f", v["\"rmse\""] * 1e3, v["\"median\""] * 1e3, v["\"max\""] * 1e3}'
}

echo "| set | map | odometry | instants with a mapped code | tight: poses there, lost, restarts | tight: ATE RMSE / median / max (mm) | single-frame: poses there | single-frame: ATE (mm) | odometry alone: ATE (mm, SE(3)-aligned) |"
echo "|---|---|---|---|---|---|---|---|---|"
for name in "${sets[@]}"; do
  set_dir=$data/$name
  ref=$set_dir/reference/trajectory.tum
  # Waymark's own map of the set (under a 10 GB address-space cap, as scripts/accuracy-tagslam.sh).
  prlimit --as=10000000000 -- "$waymark" map build "$set_dir" --out "$work/map.json" --no-covariance \
    > "$work/build.txt"
  offset=$(sed -n 's/.*time offset estimated at \([-0-9.e+]*\) s.*: applied.*/\1/p' "$work/build.txt")
  input=$set_dir
  localize_options=()
  odometry="none"
  odometry_ate="—"
  if [ -f "$set_dir/odometry.tum" ]; then
    odometry="yes"
    odometry_ate=$(ate_mm "$set_dir/odometry.tum" "$ref" se3)
    [ -n "$offset" ] && localize_options+=(--odometry-time-offset "$offset") && odometry="yes, offset $offset s"
    if [ "$name" = tagslam-test22 ]; then
      input=$work/vio
      rm -rf "$input" && mkdir "$input"
      for f in "$set_dir"/*; do ln -s "$(cd "$(dirname "$f")" && pwd)/$(basename "$f")" "$input/"; done
      rm "$input/dataset.yaml"
      grep -v '^odometry_sigma:' "$set_dir/dataset.yaml" > "$input/dataset.yaml"
      echo "$vio_sigma" >> "$input/dataset.yaml"
      odometry="$odometry, VIO model"
    fi
  fi
  # Instants (stamps, to 0.1 ms) with a code (every code of these sets is in both maps), and how
  # many of them have a pose in a TUM file.
  grep -v '"markers": \[\]' "$set_dir/detections.jsonl" | sed 's/^{"t": *\([0-9.e+-]*\),.*/\1/' |
    awk '{printf "%.4f\n", $1}' | sort -u > "$work/instants.txt"
  posed() { grep -v '^#' "$1" | awk '{printf "%.4f\n", $1}' | sort -u | comm -12 - "$work/instants.txt" | wc -l; }
  for map in tagslam waymark; do
    map_file=$set_dir/reference/markers.json
    [ "$map" = waymark ] && map_file=$work/map.json
    for mode in tight single-frame; do
      "$waymark" localize "$input" --map "$map_file" --out "$work/$mode.tum" --mode "$mode" \
        ${localize_options[@]+"${localize_options[@]}"} > "$work/$mode.txt"
    done
    lost=$(sed -n 's/^initializations: \([0-9]*\) (relocalizations \([0-9]*\)), times lost \([0-9]*\).*/\3, \2/p' "$work/tight.txt")
    printf '| %s | %s | %s | %s | %s, %s | %s | %s | %s | %s |\n' "$name" "$map" "$odometry" \
      "$(wc -l < "$work/instants.txt")" "$(posed "$work/tight.tum")" "$lost" "$(ate_mm "$work/tight.tum" "$ref" none)" \
      "$(posed "$work/single-frame.tum")" "$(ate_mm "$work/single-frame.tum" "$ref" none)" "$odometry_ate"
  done
done
