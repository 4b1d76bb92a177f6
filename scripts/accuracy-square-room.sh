#!/usr/bin/env bash
# Several ID-less squares ([Seki], issue 16) through the binary, per seed:
#   waymark sim square-ceiling --out D --seed N --render --set place.squares=S   (a larger room)
#   waymark detect D --out D/detections.jsonl --families square                  (ids "*")
#   waymark map build D --out map.json       with D/markers.json cut to its first square (the anchor)
#   waymark localize D --map D/markers.json --start-pose X,Y,YAW_DEG --out run.tum   (the true map)
#   waymark localize D --map map.json       --start-pose X,Y,YAW_DEG --out run.tum   (the built map)
#   waymark eval ... --align none against D/groundtruth/trajectory.tum
# The start pose is the truth's first pose moved by +0.2 m in x and +5 deg (a rough one).
# Prints per seed: the squares found by the map build and the largest position error of a square
# (mm), the ATE RMSE (mm) and heading RMSE (deg) with each map, the pairs with a square.
# Usage: scripts/accuracy-square-room.sh [BUILD_DIR] [FIRST_SEED] [LAST_SEED] [SQUARES] [SIM ARGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=${1:-build}/waymark
first=${2:-1}
last=${3:-1}
squares=${4:-2}
shift $(($# < 4 ? $# : 4))
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

json_after() { sed -n "/\"$2\"/,\$p" "$1" | grep -o "\"$3\": *[-0-9.eE+]*" | head -n 1 | sed 's/.*: *//'; }

# Largest distance (mm) between the squares of map $1 and the nearest square of map $2, and their count.
map_error() {
  python3 - "$1" "$2" <<'EOF'
import json, sys
built = json.load(open(sys.argv[1]))["markers"]
truth = json.load(open(sys.argv[2]))["markers"]
def pos(m): return m["T_world_marker"]["t"] if "T_world_marker" in m else m["position"]
worst = 0.0
for b in built:
    p = pos(b)
    worst = max(worst, min(sum((p[i] - pos(t)[i]) ** 2 for i in range(3)) ** 0.5 for t in truth))
print(len(built), "%.1f" % (1000 * worst))
EOF
}

echo "| seed | squares mapped | worst square position error (mm) | ATE RMSE, true map (mm) | heading RMSE (deg) | ATE RMSE, built map (mm) | heading RMSE (deg) | pairs with a square |"
echo "|---|---|---|---|---|---|---|---|"
for seed in $(seq "$first" "$last"); do
  d="$work/d$seed"
  "$waymark" sim square-ceiling --out "$d" --seed "$seed" --render --set place.squares="$squares" "$@" 2>/dev/null
  "$waymark" detect "$d" --out "$d/detections.jsonl" --families square 2>/dev/null
  gt="$d/groundtruth/trajectory.tum"
  start=$(awk '/^[0-9]/ && !done { x = $2; y = $3; qz = $7; qw = $8; done = 1 }
    END { printf "%.4f,%.4f,%.3f", x + 0.2, y, 2 * atan2(qz, qw) * 180 / 3.14159265358979 + 5 }' "$gt")
  cp "$d/markers.json" "$work/truth.json"
  python3 - "$d/markers.json" <<'EOF'
import json, sys
m = json.load(open(sys.argv[1]))
m["markers"] = m["markers"][:1]
json.dump(m, open(sys.argv[1], "w"), indent=1)
EOF
  "$waymark" map build "$d" --out "$work/map.json" >/dev/null 2>&1
  read -r mapped worst < <(map_error "$work/map.json" "$work/truth.json")
  cp "$work/truth.json" "$d/markers.json"
  row=()
  for map in "$d/markers.json" "$work/map.json"; do
    "$waymark" localize "$d" --map "$map" --start-pose "$start" --out "$work/run.tum" >/dev/null 2>&1
    "$waymark" eval --est "$work/run.tum" --gt "$gt" --align none --json "$work/eval.json" >/dev/null
    row+=("$(awk -v a="$(json_after "$work/eval.json" ate rmse)" 'BEGIN { printf "%.1f", a * 1000 }')")
    row+=("$(printf '%.3f' "$(json_after "$work/eval.json" yaw_deg rmse)")")
  done
  pairs=$(grep -c '"square"' "$d/detections.jsonl" || true)
  total=$(wc -l <"$d/detections.jsonl")
  printf '| %s | %s | %s | %s | %s | %s | %s | %s/%s |\n' "$seed" "$mapped" "$worst" "${row[0]}" "${row[1]}" \
    "${row[2]}" "${row[3]}" "$pairs" "$total"
  rm -rf "$d"
done
