#!/usr/bin/env bash
# Issue 14, item 6: the live loop detecting where the map says.
# Default: the demo run. Builds the map from data/demo/survey's images (`waymark map build
# --detect-images`), feeds data/demo/run (odometry and image lines, in stamp order) to `waymark
# localize --live` once with the whole frame every time (--full-frame-every 1) and once with the
# default predicted regions (--full-frame-every 10), and prints each run's detection summary
# (images per kind and their CPU time) and the position error of its poses against the run's
# ground truth.
# --corridor: the same on 1280x960 frames: `waymark sim corridor` surveys (seed 1) for the map and
# renders a separate run (seed 2, camera.image_scale=2, a frame every 0.5 s per camera).
# Usage: scripts/live-regions-demo.sh [--corridor] [BINARY]   (default build/waymark; temp dir)
set -euo pipefail
cd "$(dirname "$0")/.."
corridor=0
if [[ "${1:-}" == --corridor ]]; then
  corridor=1
  shift
fi
bin=${1:-build/waymark}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if [[ $corridor == 1 ]]; then
  "$bin" sim corridor --out "$tmp/survey" --seed 1 --set camera.image_scale=2 > /dev/null
  "$bin" map build "$tmp/survey" --out "$tmp/map.json" > /dev/null
  "$bin" sim corridor --out "$tmp/run" --seed 2 --set camera.image_scale=2 --render --render-every 5 > /dev/null
  run="$tmp/run"
else
  "$bin" map build data/demo/survey --detect-images --out "$tmp/map.json" > /dev/null
  run="$PWD/data/demo/run"
fi
python3 - "$run" > "$tmp/live.jsonl" <<'PY'
import csv, json, sys
run = sys.argv[1]
lines = []
for row in open(run + "/odometry.tum"):
    p = row.split()
    if len(p) != 8 or row.startswith("#"):
        continue
    t = float(p[0])
    lines.append((t, 0, json.dumps({"t": t, "T_odom_robot": {"t": [float(x) for x in p[1:4]],
                                                               "q_xyzw": [float(x) for x in p[4:8]]}})))
for r in csv.DictReader(open(run + "/images.csv")):
    lines.append((float(r["t"]), 1, json.dumps({"t": float(r["t"]), "camera": r["camera"],
                                                 "image": run + "/" + r["path"]})))
lines.sort(key=lambda e: (e[0], e[1]))
print("\n".join(e[2] for e in lines))
PY
for n in 1 10; do
  echo "--full-frame-every $n (load average $(cut -d' ' -f1 /proc/loadavg)):"
  "$bin" localize "$run" --map "$tmp/map.json" --live --detect-budget-ms 0 --full-frame-every "$n" \
    < "$tmp/live.jsonl" > "$tmp/poses-$n.jsonl" 2> "$tmp/err-$n.txt"
  grep -E '^detection: .*(predicted regions|reading the image files)' "$tmp/err-$n.txt"
  python3 - "$run/groundtruth/trajectory.tum" "$tmp/poses-$n.jsonl" <<'PY'
import bisect, json, math, sys
gt = [list(map(float, l.split())) for l in open(sys.argv[1]) if l.strip() and not l.startswith("#")]
ts = [g[0] for g in gt]
def at(t):
    i = min(max(bisect.bisect_left(ts, t), 1), len(gt) - 1)
    a, b = gt[i - 1], gt[i]
    w = (t - a[0]) / (b[0] - a[0])
    return [a[k] + w * (b[k] - a[k]) for k in (1, 2, 3)]
errors, corrected = [], 0
for line in open(sys.argv[2]):
    o = json.loads(line)
    corrected += o["accepted"] > 0
    if "T_world_robot" in o:
        errors.append(math.dist(o["T_world_robot"]["t"], at(o["t"])))
print("  %d poses, %d frames corrected by a code; position error RMS %.2f mm, max %.2f mm" % (
    len(errors), corrected, 1000 * math.sqrt(sum(e * e for e in errors) / len(errors)), 1000 * max(errors)))
PY
done
