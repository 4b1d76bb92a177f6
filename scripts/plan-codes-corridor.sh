#!/usr/bin/env bash
# `waymark plan-codes` on the corridor scenario and its verification (docs/planning.md):
#   the rig and the path: a sim corridor survey (seed 1000): its cameras, odometry noise and true path
#   the floor plan: the corridor's eight walls (place.* defaults: 12 x 8 m loop, 1.2 m wide)
#   plan-codes --target-mm TARGET -> planned.json, with its predicted map error
#   verification: sim corridor --markers planned.json (seeds 1..N) -> map build -> eval --map
#   the trade-off: the same for fixed spacings (plan-codes --spacings S), the 1 m one being the
#   scenario's default layout, each predicted and measured on the same seeds.
# Prints Markdown tables. Usage: scripts/plan-codes-corridor.sh [BUILD_DIR] [TARGET_MM] [SEEDS] [SPACINGS]
# (defaults: build, 10, 5, "0.7 1 1.4 2 2.8")
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build}/waymark
target=${2:-10}
seeds=${3:-5}
spacings=${4:-"0.7 1 1.4 2 2.8"}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

"$waymark" sim corridor --seed 1000 --out "$work/rig" 2>/dev/null
cat >"$work/world.yaml" <<YAML
format: waymark-floor-plan
version: 1
ceiling_height_m: 2.5
rig: rig
code_sizes_m: [0.10]
code_height_m: 0.30
detect: {min_range_m: 0.2, max_range_m: 0.8, max_angle_deg: 60, border_px: 2, pixel_sigma_px: 0.5, camera_hz: 10}
walls:
  - {from: [0.6, 0.6], to: [11.4, 0.6]}
  - {from: [11.4, 0.6], to: [11.4, 7.4]}
  - {from: [11.4, 7.4], to: [0.6, 7.4]}
  - {from: [0.6, 7.4], to: [0.6, 0.6]}
  - {from: [-0.6, -0.6], to: [12.6, -0.6]}
  - {from: [12.6, -0.6], to: [12.6, 8.6]}
  - {from: [12.6, 8.6], to: [-0.6, 8.6]}
  - {from: [-0.6, 8.6], to: [-0.6, -0.6]}
YAML
path="$work/rig/groundtruth/trajectory.tum"

# measure LAYOUT.json: mean and max over the seeds of the measured map position RMSE (mm), and the
# build's own prediction on the first seed.
measure() {
  local layout=$1 sum=0 max=0 predicted=
  for seed in $(seq 1 "$seeds"); do
    local d="$work/survey-$seed"
    "$waymark" sim corridor --markers "$layout" --seed "$seed" --out "$d" --force 2>/dev/null
    "$waymark" map build "$d" --out "$work/map.json" >"$work/build.txt" 2>&1
    local e
    e=$("$waymark" eval --map "$work/map.json" --gt-map "$d/groundtruth/markers.json" | awk '/^map position/ { print $4 }')
    sum=$(awk -v s="$sum" -v e="$e" 'BEGIN { print s + e }')
    max=$(awk -v m="$max" -v e="$e" 'BEGIN { print (e > m ? e : m) }')
  done
  awk -v s="$sum" -v n="$seeds" -v m="$max" 'BEGIN { printf "%.1f | %.1f", 1000 * s / n, 1000 * m }'
}

echo "plan-codes --target-mm $target:"
echo
"$waymark" plan-codes "$work/world.yaml" --path "$path" --target-mm "$target" --out "$work/planned.json" \
  2>"$work/plan.txt" >"$work/plan-out.txt" || { cat "$work/plan.txt" >&2; exit 1; }
cat "$work/plan-out.txt"
sed 's/^/    /' "$work/plan.txt"
echo
echo "| layout | codes | predicted map error (mm, aligned RMS) | predicted online (mm, RMS) | measured map RMSE, mean of $seeds seeds (mm) | max (mm) | measured / predicted |"
echo "|---|---|---|---|---|---|---|"
row() {
  local label=$1 layout=$2 line=$3
  local codes predicted online measured
  codes=$(grep -o '^chosen: [0-9]*' <<<"$line" | sed 's/chosen: //')
  predicted=$(sed -n 's/.*predicted map error \([0-9.]*\) mm.*/\1/p' <<<"$line")
  online=$(sed -n 's/.*online \([0-9.]*\) mm.*/\1/p' <<<"$line")
  measured=$(measure "$layout")
  local mean=${measured%% |*}
  echo "| $label | $codes | $predicted | $online | $measured | $(awk -v m="$mean" -v p="$predicted" 'BEGIN { printf "%.2f", m / p }') |"
}
row "plan-codes --target-mm $target" "$work/planned.json" "$(head -n 1 "$work/plan-out.txt")"
for s in $spacings; do
  "$waymark" plan-codes "$work/world.yaml" --path "$path" --target-mm 1000 --spacings "$s" \
    --out "$work/fixed-$s.json" 2>/dev/null >"$work/fixed-$s.txt"
  row "every $s m" "$work/fixed-$s.json" "$(head -n 1 "$work/fixed-$s.txt")"
done
