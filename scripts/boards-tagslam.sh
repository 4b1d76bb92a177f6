#!/usr/bin/env bash
# Rigid boards on real data (docs/accuracy.md, "Real data, TagSLAM", test13): tagslam-test13's six
# anchors are the tags of one board of known layout and pose. This gives them as a rigid board
# (markers.json `boards`, docs/formats.md), the layout taken from the six anchor poses of the set's
# own markers.json (nothing from reference/), in five variants: the six anchors as given
# (baseline), the board's pose fixed, unknown with tag 60 alone fixed, a prior of 1 cm / 0.01 rad,
# unknown with no anchor; and the six tags free (size only, no board, no anchor). For each:
# `waymark map build`, `waymark map score`, one table row (observations used, RMS and median px,
# the build's summary line of the board).
# Usage: scripts/boards-tagslam.sh [BUILD_DIR]   (default: build)
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=$(realpath "${1:-build}/waymark")
set_dir=$(realpath ../shared/data/tagslam/tagslam-test13 2>/dev/null || true)
if [ -z "$set_dir" ] || [ ! -d "$set_dir" ]; then
  echo "boards-tagslam: ../shared/data/tagslam/tagslam-test13 is absent; nothing to measure" >&2
  exit 1
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 - "$set_dir" "$work" <<'PY'
import json, math, os, sys
src, work = sys.argv[1], sys.argv[2]
known = json.load(open(os.path.join(src, "markers.json")))
def rot(q):
    x, y, z, w = q
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
def quat(R):  # rotation matrix -> q_xyzw (w > 0 here: the layout's rotations are small)
    w = math.sqrt(max(0.0, 1 + R[0][0] + R[1][1] + R[2][2])) / 2
    q = [(R[2][1] - R[1][2]) / (4 * w), (R[0][2] - R[2][0]) / (4 * w), (R[1][0] - R[0][1]) / (4 * w), w]
    n = math.sqrt(sum(c * c for c in q))
    return [c / n for c in q]
anchors = [m for m in known["markers"] if "T_world_marker" in m]
R0 = rot(anchors[0]["T_world_marker"]["q_xyzw"])
t0 = anchors[0]["T_world_marker"]["t"]
layout = []
for m in anchors:  # T_board_marker = T_world_anchor0^-1 * T_world_marker
    R = rot(m["T_world_marker"]["q_xyzw"])
    t = m["T_world_marker"]["t"]
    Rb = [[sum(R0[k][i] * R[k][j] for k in range(3)) for j in range(3)] for i in range(3)]
    tb = [sum(R0[k][i] * (t[k] - t0[k]) for k in range(3)) for i in range(3)]
    layout.append({"family": m["family"], "id": m["id"], "T_board_marker": {"t": tb, "q_xyzw": quat(Rb)}})
size_only = lambda m: {k: v for k, v in m.items() if k in ("family", "id", "size_m")}
prior = [0.0] * 36
for i in range(6):
    prior[7 * i] = 0.01 ** 2
variants = {
    "board-fixed": ({"T_world_board": anchors[0]["T_world_marker"], "fixed": True}, size_only),
    "board-one-anchor": ({}, lambda m: m if m["id"] == anchors[0]["id"] else size_only(m)),
    "board-prior": ({"T_world_board": anchors[0]["T_world_marker"], "covariance": prior}, size_only),
    "board-unknown": ({}, size_only),
    "free": (None, size_only),
}
for name, (board, entry) in variants.items():
    d = os.path.join(work, name)
    os.makedirs(d)
    for f in ("detections.jsonl", "cameras", "dataset.yaml"):
        os.symlink(os.path.join(src, f), os.path.join(d, f))
    out = {"format": "waymark-map", "version": 1, "markers": [entry(dict(m)) for m in known["markers"]]}
    if board is not None:
        out["boards"] = [dict({"name": "anchor-board"}, **board, markers=layout)]
    json.dump(out, open(os.path.join(d, "markers.json"), "w"), indent=1)
PY
ln -s "$set_dir" "$work/baseline"
json_number() { grep -o "\"$2\": *[-0-9.eE+]*" "$1" | head -n 1 | sed 's/.*: *//'; }
echo "| markers.json | used | RMS (median) px | board |"
echo "|---|---|---|---|"
for v in baseline board-fixed board-one-anchor board-prior board-unknown free; do
  prlimit --as=10000000000 -- "$waymark" map build "$work/$v" --out "$work/$v.map.json" \
    --trajectory "$work/$v.tum" --no-covariance > "$work/$v.build.txt"
  "$waymark" map score "$work/$v" --map "$work/$v.map.json" --trajectory "$work/$v.tum" \
    --json "$work/$v.score.json" > /dev/null
  used=$(sed -n 's/^map:.*frames, \([0-9]*\) observations used.*/\1/p' "$work/$v.build.txt")
  board=$(sed -n 's/^note: board anchor-board: //p' "$work/$v.build.txt")
  printf '| %s | %s | %.4f (%.4f) | %s |\n' "$v" "$used" "$(json_number "$work/$v.score.json" rms_px)" \
    "$(json_number "$work/$v.score.json" median_px)" "${board:-—}"
done
