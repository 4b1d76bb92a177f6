#!/usr/bin/env bash
# The closed loop of docs/planning.md end to end through the binary:
#   survey (seed 1000) -> waymark map build -> waymark route -> waymark sim --drive (seeds 1..N)
# on sim `rooms` (room 0's centre through the door to room 1's centre, facing +y) and on sim
# `corridor` (once round the loop from corner (0, 0) back to it). Prints one Markdown table row
# per drive (from its drive.json) and a summary line per scenario: how many reached the goal
# within 5 cm with the filter never lost.
# Usage: scripts/closed-loop.sh [BUILD_DIR] [SEEDS] [OUT_DIR] [DRIVE_OPTION]
#   (defaults: build, 20, a temporary dir, none; DRIVE_OPTION e.g. --cold-start: the localizer
#   starts from its first code instead of the route's start)
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build}/waymark
seeds=${2:-20}
drive_option=${4:-}
if [[ -n ${3:-} ]]; then
  work=$3
  mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi

# One key's value in a drive.json.
key() { grep -o "\"$2\": *[^,}]*" "$1" | head -n 1 | sed 's/.*: *//'; }

# Metres as millimetres with one decimal ("-" when absent).
mm() { if [[ -z $1 ]]; then echo -; else awk -v v="$1" 'BEGIN { printf "%.1f", v * 1000 }'; fi; }

# drive SCENARIO ROUTE_ARGS...: survey, map, route, then the drives.
drive() {
  local scenario=$1
  shift
  local dir="$work/$scenario"
  mkdir -p "$dir"
  "$waymark" sim "$scenario" --seed 1000 --out "$dir/survey" --force 2>/dev/null
  "$waymark" map build "$dir/survey" --out "$dir/map.json" >/dev/null 2>&1
  "$waymark" route "$dir/map.json" --survey "$dir/survey" "$@" --out "$dir/route.json" 2>"$dir/route.txt" ||
    { cat "$dir/route.txt" >&2; exit 1; }
  echo
  echo "$scenario: $(cat "$dir/route.txt")"
  echo
  echo "| seed | reached | goal error (mm) | estimate - truth at the end (mm) | max estimate error (mm) | frames lost | times lost | times suspect | length (m) | time (s) |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
  local good=0
  for seed in $(seq 1 "$seeds"); do
    local out="$dir/drive-$seed"
    "$waymark" sim "$scenario" --drive "$dir/route.json" --localize "$dir/map.json" --seed "$seed" \
      --out "$out" --force $drive_option 2>/dev/null || true
    local j="$out/drive.json"
    local err
    err=$(key "$j" goal_error_m)
    printf '| %s | %s | %s | %s | %s | %s | %s | %s | %.2f | %.1f |\n' "$seed" "$(key "$j" reached)" \
      "$(mm "$err")" "$(mm "$(key "$j" estimate_error_m)")" "$(mm "$(key "$j" max_estimate_error_m)")" \
      "$(key "$j" frames_lost)" \
      "$(key "$j" times_lost)" "$(key "$j" times_suspect)" "$(key "$j" path_length_m)" "$(key "$j" duration_s)"
    if [[ $(key "$j" reached) == true && $(key "$j" times_lost) == 0 && $(awk -v v="$err" 'BEGIN { print (v < 0.05) }') == 1 ]]; then
      good=$((good + 1))
    fi
  done
  echo
  echo "$scenario: $good of $seeds drives reached the goal within 5 cm with the filter never lost"
}

# rooms has no anchors: the map's frame is the survey's first pose (room 0's centre, facing +x),
# so room 1's centre is (4, 0) in it.
drive rooms --from 0,0,0 --to 4,0,1.5707963
drive corridor --from 0,0,0 --via "12,0;12,8;0,8" --to 0,0,0
