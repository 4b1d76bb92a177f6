#!/usr/bin/env bash
# Regenerates data/demo/, the small dataset `waymark demo` runs on, with the waymark binary alone:
#   survey/  a rendered survey of a small `corridor` loop (seed 1): the robot drives once round
#            at 0.35 m/s, counter-clockwise on the centre line, from corner 0; images at 2 Hz from
#            both cameras (each code in about three frames)
#   run/     a separate run through the same place (seed 2): at 0.5 m/s, clockwise, from the
#            opposite corner, on a loop 0.05 m inside the centre line; images at 1 Hz
# Both hold images (PNG, 8-bit gray), images.csv, odometry.tum, cameras/, markers.json (four anchors
# and every code's size), dataset.yaml and groundtruth/ (trajectory, markers, exact image corners).
# The simulator's own noisy detections (detections.jsonl) are removed: the demo detects the images.
#
# Small for git (under 6 MB): 320x240 cameras (camera.image_scale 0.5) with 12 cm codes (about
# 56 px wide at the 0.48 m wall distance), no pixel noise and a fainter wall texture (PNG
# compresses both badly), a 5 x 2.5 m loop, odometry at 10 Hz. The place is fixed by the keys;
# the seeds draw only the noise. Four anchors (C000-C003, 3 m along the first wall) give the map
# its world frame: with two (1 m apart) the map's heading error doubled the run's world-frame ATE.
#
# Usage: scripts/make-demo-data.sh [WAYMARK_BINARY]   (default: build/waymark; run from anywhere)
# Takes several minutes (every image is ray-traced).
set -euo pipefail
cd "$(dirname "$0")/.."
waymark=$(realpath "${1:-build/waymark}")
out=data/demo

place=(
  --set place.loop_length_m=5 --set place.loop_width_m=2.5 --set place.marker_size_m=0.12
  --set place.anchors=4
  --set camera.image_scale=0.5 --set rate.odometry_hz=10
  --set render.noise_sigma=0 --set render.texture_contrast=0.08
)
survey_path=(--set robot.speed_mps=0.35 --set rate.camera_hz=2)
run_path=(--set robot.speed_mps=0.5 --set rate.camera_hz=1
          --set path.clockwise=true --set path.start_corner=2 --set path.inset_m=0.05)

staging=$(mktemp -d "${out%/*}/.demo-staging.XXXXXX")
trap 'rm -rf "$staging"' EXIT
chmod 755 "$staging"
"$waymark" sim corridor --out "$staging/survey" --seed 1 "${place[@]}" "${survey_path[@]}" --render
"$waymark" sim corridor --out "$staging/run" --seed 2 "${place[@]}" "${run_path[@]}" --render
rm "$staging/survey/detections.jsonl" "$staging/run/detections.jsonl"
cat > "$staging/README.md" <<'README'
# data/demo: the dataset of `waymark demo`

Made by `scripts/make-demo-data.sh` (read it for every key); do not edit by hand.

- `survey/`: a rendered survey of a small corridor loop (5 x 2.5 m centre line, 1.2 m wide, 12 cm
  QR codes every metre on both walls, the first four of them anchors; two side cameras of
  320x240, wheel odometry at 10 Hz, images at 2 Hz, 0.35 m/s). `waymark demo` detects the codes
  in its images and learns the map from them.
- `run/`: a second run through the same place at 0.5 m/s, clockwise from the opposite corner on a
  loop 0.05 m inside the centre line, images at 1 Hz. `waymark demo` localizes it against the map.

Each is a dataset directory (docs/design.md) with `groundtruth/` (true trajectory, true marker poses,
exact corners of every code in each image) and `sim_config.yaml` (every simulator key used).
README

rm -rf "$out.old"
if [ -d "$out" ]; then mv "$out" "$out.old"; fi
mv "$staging" "$out"
rm -rf "$out.old"
trap - EXIT
du -sh "$out" >&2
