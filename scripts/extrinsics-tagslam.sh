#!/usr/bin/env bash
# Extrinsic self-calibration on a multi-camera survey (issue 13, item 4; docs/accuracy.md):
#
#   scripts/extrinsics-tagslam.sh BUILD_DIR SET_DIR OUT_DIR [DEG] [M] [SIGMA_RAD] [SIGMA_M] [WIGGLE_RAD WIGGLE_M]
#
# Copies the dataset SET_DIR (e.g. ../shared/data/tagslam/tagslam-test6) to OUT_DIR/perturbed,
# moves every camera but the first of dataset.yaml's list off its given mount by DEG degrees
# (default 2) about an axis and M metres (default 0.03) along a direction that differ per camera
# (fixed, not random), and gives those cameras T_robot_camera_sigma [SIGMA_RAD, SIGMA_M]
# (default [0.05, 0.05]) and, with WIGGLE_RAD WIGGLE_M, every camera frame_wiggle_sigma
# [WIGGLE_RAD, WIGGLE_M] (each frame's pose of a camera may move that much off its mount). Then:
#   1. `waymark map build` on the set as given (OUT_DIR/given.*),
#   2. `waymark map build` on the perturbed copy with --cameras-out OUT_DIR/calibrated/cameras,
#   3. prints, per perturbed camera, how far the given, the perturbed and the calibrated mounts
#      are from the set's own (rotation deg, translation mm),
#   4. `waymark map score` of both builds on the same observations, each with its own cameras
#      (the given ones, and the calibrated ones written by step 2).
# Each build runs under a 10 GB address-space cap.
set -euo pipefail
if [[ $# -lt 3 ]]; then
  echo "usage: $0 BUILD_DIR SET_DIR OUT_DIR [DEG] [M] [SIGMA_RAD] [SIGMA_M] [WIGGLE_RAD WIGGLE_M]" >&2
  exit 2
fi
build=$1
set_dir=$2
out=$3
deg=${4:-2}
metres=${5:-0.03}
sigma_rad=${6:-0.05}
sigma_m=${7:-0.05}
wiggle_rad=${8:-}
wiggle_m=${9:-}
waymark="$build/waymark"
[[ -x "$waymark" ]] || { echo "$0: $waymark: not built" >&2; exit 1; }
[[ -f "$set_dir/dataset.yaml" ]] || { echo "$0: $set_dir/dataset.yaml: no such file" >&2; exit 1; }
mkdir -p "$out"
# Only our own outputs are replaced; nothing else in OUT_DIR is touched.
rm -rf "$out/perturbed" "$out/calibrated"
mkdir -p "$out/perturbed/cameras" "$out/calibrated"
for f in "$set_dir"/*; do
  [[ "$(basename "$f")" == cameras ]] && continue
  ln -s "$(realpath "$f")" "$out/perturbed/$(basename "$f")"
  ln -s "$(realpath "$f")" "$out/calibrated/$(basename "$f")"
done

python3 - "$set_dir" "$out/perturbed/cameras" "$deg" "$metres" "$sigma_rad" "$sigma_m" "$wiggle_rad" "$wiggle_m" <<'EOF'
import math, os, re, sys
set_dir, out_dir = sys.argv[1], sys.argv[2]
deg, metres, sigma_rad, sigma_m = map(float, sys.argv[3:7])
wiggle = sys.argv[7:9] if sys.argv[7] else None
names = re.search(r"cameras:\s*\[([^\]]*)\]", open(os.path.join(set_dir, "dataset.yaml")).read()).group(1)
names = [n.strip() for n in names.split(",") if n.strip()]

def qmul(a, b):  # xyzw
    ax, ay, az, aw = a; bx, by, bz, bw = b
    return [aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz]

for i, name in enumerate(names):
    text = open(os.path.join(set_dir, "cameras", name + ".yaml")).read()
    if i > 0:
        t = [float(v) for v in re.search(r"\bt:\s*\[([^\]]*)\]", text).group(1).split(",")]
        q = [float(v) for v in re.search(r"q_xyzw:\s*\[([^\]]*)\]", text).group(1).split(",")]
        # A fixed axis and direction per camera: unit vectors that differ from camera to camera.
        axis = [math.cos(1.3 * i), math.sin(1.3 * i), 0.5]
        n = math.sqrt(sum(a * a for a in axis)); axis = [a / n for a in axis]
        direction = [math.sin(2.1 * i), 0.4, math.cos(2.1 * i)]
        n = math.sqrt(sum(d * d for d in direction)); direction = [d / n for d in direction]
        half = math.radians(deg) / 2
        dq = [axis[0] * math.sin(half), axis[1] * math.sin(half), axis[2] * math.sin(half), math.cos(half)]
        q = qmul(q, dq)
        t = [t[k] + metres * direction[k] for k in range(3)]
        text = re.sub(r"\bt:\s*\[[^\]]*\]", "t: [%.9f, %.9f, %.9f]" % tuple(t), text)
        text = re.sub(r"q_xyzw:\s*\[[^\]]*\]", "q_xyzw: [%.9f, %.9f, %.9f, %.9f]" % tuple(q), text)
        text = text.rstrip("\n") + "\nT_robot_camera_sigma: [%g, %g]\n" % (sigma_rad, sigma_m)
    if wiggle:  # every camera, the reference too: the frame's pose is then the rig's, not one camera's
        text = text.rstrip("\n") + "\nframe_wiggle_sigma: [%s, %s]\n" % tuple(wiggle)
    open(os.path.join(out_dir, name + ".yaml"), "w").write(text)
EOF

build_map() {  # DATASET PREFIX [extra args]
  local dataset=$1 prefix=$2
  shift 2
  prlimit --as=10000000000 -- /usr/bin/time -f "%e s wall, %M KB peak RSS" \
    "$waymark" map build "$dataset" --out "$prefix.map.json" --trajectory "$prefix.tum" \
    --report "$prefix.report.json" --no-covariance "$@" > "$prefix.summary.txt" 2> "$prefix.time.txt"
  echo "$prefix: $(tail -1 "$prefix.time.txt"), $(grep -m1 '^map:' "$prefix.summary.txt")"
}
build_map "$set_dir" "$out/given"
build_map "$out/perturbed" "$out/perturbed" --cameras-out "$out/calibrated/cameras"
grep '^camera \(mount\|wiggle\)' "$out/perturbed.summary.txt" || true

python3 - "$set_dir/cameras" "$out/perturbed/cameras" "$out/calibrated/cameras" <<'EOF'
import math, os, re, sys
given, perturbed, calibrated = sys.argv[1:4]
def pose(path):
    text = open(path).read()
    t = [float(v) for v in re.search(r"\bt:\s*\[([^\]]*)\]", text).group(1).split(",")]
    q = [float(v) for v in re.search(r"q_xyzw:\s*\[([^\]]*)\]", text).group(1).split(",")]
    return t, q
def apart(a, b):
    (ta, qa), (tb, qb) = a, b
    dot = abs(sum(x * y for x, y in zip(qa, qb))) / math.sqrt(sum(x * x for x in qa) * sum(x * x for x in qb))
    return math.degrees(2 * math.acos(min(1.0, dot))), 1e3 * math.dist(ta, tb)
print("camera: perturbed mount off the set's (deg, mm) -> calibrated mount off the set's (deg, mm)")
for name in sorted(os.listdir(calibrated)):
    g = pose(os.path.join(given, name))
    p = pose(os.path.join(perturbed, name))
    c = pose(os.path.join(calibrated, name))
    print("  %s: %.3f deg, %.1f mm -> %.3f deg, %.1f mm" % ((name[:-5],) + apart(p, g) + apart(c, g)))
EOF

for prefix in given perturbed; do
  dataset=$set_dir
  [[ $prefix == perturbed ]] && dataset=$out/calibrated
  "$waymark" map score "$dataset" --map "$out/$prefix.map.json" --trajectory "$out/$prefix.tum" \
    --solve-missing-markers --json "$out/$prefix.score.json" > "$out/$prefix.score.txt"
  echo "score of the $prefix build ($( [[ $prefix == given ]] && echo "the set's cameras" || echo "calibrated cameras")): $(grep -m1 -i 'rms' "$out/$prefix.score.txt")"
done
