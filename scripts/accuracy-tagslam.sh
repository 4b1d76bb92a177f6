#!/usr/bin/env bash
# Mapping on the real TagSLAM sets (../shared/data/tagslam) for docs/accuracy.md: for each set,
# `waymark map build`, then `waymark map score` of our map and smoothed trajectory and of TagSLAM's
# reference (its trajectory held fixed, the tags its markers.json lacks solved on the same corners),
# printing a Markdown table: reprojection RMS (px, over corners) of both on every observation of
# the set, ours also on exactly the observations the reference scores (`--frames-of` its trajectory:
# the frames it has a pose for), observations used / rejected by our build, the components of our map, the build's
# wall time and peak memory (/usr/bin/time -v; every build runs under a 10 GB address-space cap,
# prlimit --as), the odometry time offset our build found, and test16's line fit of the tag
# centres (mm).
# Usage: scripts/accuracy-tagslam.sh [BUILD_DIR] [SET...]   (default: build, all six sets)
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build}/waymark
shift || true
sets=("$@")
[ ${#sets[@]} -eq 0 ] && sets=(tagslam-test16 tagslam-test17 tagslam-test22 tagslam-test13 tagslam-test10-priors
                              tagslam-test6)
data=../shared/data/tagslam
if [ ! -d "$data" ]; then
  echo "accuracy-tagslam: $data is absent (the shared data folder); nothing to measure" >&2
  exit 1
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# First number after a key in waymark map score's JSON ("rms_px" first appears under "all").
json_number() { grep -o "\"$2\": *[-0-9.eE+]*" "$1" | head -n 1 | sed 's/.*: *//'; }

echo "| set | observations | ours: used / rejected | components | ours: RMS (median) px | ours on the reference's frames: RMS (median) px, scored | reference: RMS (median) px | reference: scored | build time, peak memory | odometry offset (s) | line fit of the tag centres, ours / reference |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for name in "${sets[@]}"; do
  set_dir=$data/$name
  /usr/bin/time -v -o "$work/$name.time.txt" prlimit --as=10000000000 -- \
    "$waymark" map build "$set_dir" --out "$work/$name.map.json" --trajectory "$work/$name.tum" \
    --no-covariance > "$work/$name.build.txt"
  wall=$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' "$work/$name.time.txt")
  rss_mb=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$work/$name.time.txt" | awk '{printf "%.0f", $1 / 1024}')
  components=$(sed -n 's/^map:.* in \([0-9]*\) component(s).*/\1/p' "$work/$name.build.txt")
  line_args=()
  [ "$name" = tagslam-test16 ] && line_args=(--line)
  "$waymark" map score "$set_dir" --map "$work/$name.map.json" --trajectory "$work/$name.tum" \
    "${line_args[@]}" --json "$work/$name.ours.json" > /dev/null
  "$waymark" map score "$set_dir" --map "$work/$name.map.json" --trajectory "$work/$name.tum" \
    --frames-of "$set_dir/reference/trajectory.tum" --json "$work/$name.common.json" > /dev/null
  "$waymark" map score "$set_dir" --map "$set_dir/reference/markers.json" \
    --trajectory "$set_dir/reference/trajectory.tum" --solve-missing-markers "${line_args[@]}" \
    --json "$work/$name.ref.json" > /dev/null
  used=$(sed -n 's/^map:.*frames, \([0-9]*\) observations used.*/\1/p' "$work/$name.build.txt")
  rejected=$(sed -n 's/^outliers rejected: \([0-9]*\).*/\1/p' "$work/$name.build.txt")
  offset=$(sed -n 's/.*time offset estimated at \([-0-9.]*\) s.*: applied$/\1/p' "$work/$name.build.txt")
  if [ ! -f "$set_dir/odometry.tum" ]; then offset="— (no odometry)"; fi
  line="—"
  if [ "$name" = tagslam-test16 ]; then
    line=$(printf '%.1f / %.1f mm RMS (max %.1f / %.1f)' \
      "$(json_number "$work/$name.ours.json" rms_m | awk '{print $1 * 1000}')" \
      "$(json_number "$work/$name.ref.json" rms_m | awk '{print $1 * 1000}')" \
      "$(json_number "$work/$name.ours.json" max_m | awk '{print $1 * 1000}')" \
      "$(json_number "$work/$name.ref.json" max_m | awk '{print $1 * 1000}')")
  fi
  printf '| %s | %s | %s / %s | %s | %.3f (%.3f) | %.3f (%.3f), %s | %.3f (%.3f) | %s | %s, %s MiB | %s | %s |\n' "$name" \
    "$(json_number "$work/$name.ours.json" observations_total)" "$used" "$rejected" "$components" \
    "$(json_number "$work/$name.ours.json" rms_px)" "$(json_number "$work/$name.ours.json" median_px)" \
    "$(json_number "$work/$name.common.json" rms_px)" "$(json_number "$work/$name.common.json" median_px)" \
    "$(json_number "$work/$name.common.json" scored)" \
    "$(json_number "$work/$name.ref.json" rms_px)" "$(json_number "$work/$name.ref.json" median_px)" \
    "$(json_number "$work/$name.ref.json" scored)" "$wall" "$rss_mb" "${offset:-0}" "$line"
done
