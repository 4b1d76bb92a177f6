#!/usr/bin/env bash
# Every MRCLAM figure of docs/accuracy.md ("Real robots: MRCLAM"), on one run of the UTIAS MRCLAM
# dataset (default: ../shared/data/mrclam/MRCLAM_Dataset6; any other run directory works the same,
# nothing here is specific to run 6):
#   1. waymark import mrclam RUN --known-start   (dead reckoning per robot, misreads counted)
#   2. waymark map build robot1 ... robot5        (one map of all five robots, smoothed trajectories;
#      the default range model, depth: each range read as a depth with its scale estimated)
#   3. waymark eval: landmark RMSE after SE(2) alignment; per robot ATE and RPE (1 m) of the
#      smoothed trajectory and of dead reckoning after SE(2) alignment; a top-view SVG per robot;
#      the same map and trajectories built with --range-model distance (the build before 2026-11-26)
#   4. waymark map build robot1 robot2 robot3; waymark localize robot4 and robot5 against it
#      (ATE in the map's frame, NEES): the map's landmark errors as states of the EKF (default),
#      considered (Schmidt), in each sighting's noise, ignored (the map taken as exact: the
#      filter before the map had a covariance), and a control against the true landmark
#      positions; the map's covariance against its error (scripts/map-covariance-check.py); the
#      EKF without the map's sensor prior on the distance-model map of robots 1-3 (the filter before)
#   5. leave-out splits: map of robots 3, 4, 5 localizing 1 and 2; map of 1, 2, 4 localizing 3 and 5
# The maps of step 4 and 5 are built with --calibrate-online (the EKF's variance factor by leaving
# each mapped robot out; waymark localize scales its reported covariance by it, docs/online.md).
# Online, the odometry calibration is a Gauss-Markov state whose correlation time the map build fits
# from the mapped robots' smoothed trajectories against their odometry (no ground truth; map.json
# range_bearing_sensor calibration_time_s, waymark localize's default); each online run is repeated
# with the calibration constant (--calibration-time 0, the filter before).
# (scripts/odometry-calibration-time.py is the same fit in Python, a diagnostic: not run here.)
# Usage: scripts/accuracy-mrclam.sh [RUN_DIR] [OUT_DIR]   (OUT_DIR default: out/mrclam; needs
# build/waymark: scripts/build.sh --target waymark)
set -euo pipefail
run=${1:-}
out=${2:-}
if [[ -n "$run" && "$run" != /* ]]; then run="$PWD/$run"; fi
if [[ -n "$out" && "$out" != /* ]]; then out="$PWD/$out"; fi
cd "$(dirname "$0")/.."
run=${run:-../shared/data/mrclam/MRCLAM_Dataset6}
out=${out:-out/mrclam}
waymark=${WAYMARK_BINARY:-./build/waymark}
mkdir -p "$out"

echo "== import (dead reckoning from the true start pose, and after SE(2) alignment)"
"$waymark" import mrclam "$run" --out "$out/data" --known-start
robots=()
for dir in "$out"/data/robot*; do robots+=("$(basename "$dir")"); done

echo "== one map of all robots"
"$waymark" map build "${robots[@]/#/$out/data/}" --out "$out/map-all.json" \
  --trajectory-dir "$out/smoothed-all" --report "$out/map-all-report.json"
gt_map="$out/data/${robots[0]}/groundtruth/markers.json"
echo "== landmark error after SE(2) alignment"
"$waymark" eval --map "$out/map-all.json" --gt-map "$gt_map" --json "$out/map-all-eval.json"

for robot in "${robots[@]}"; do
  gt="$out/data/$robot/groundtruth/trajectory.tum"
  echo "== $robot: smoothed (all robots' map)"
  "$waymark" eval --est "$out/smoothed-all/$robot.tum" --gt "$gt" --align se2 --max-dt 0.02 \
    --rpe-delta 1 --rpe-unit m --markers "$out/map-all.json" --gt-map "$gt_map" \
    --json "$out/$robot-smoothed-eval.json" --plot "$out/$robot-smoothed.svg"
  echo "== $robot: dead reckoning"
  "$waymark" eval --est "$out/data/$robot/odometry.tum" --gt "$gt" --align se2 --max-dt 0.02 \
    --rpe-delta 1 --rpe-unit m --json "$out/$robot-dead-reckoning-eval.json"
done

echo "== one map of all robots, each range read as a distance (--range-model distance)"
"$waymark" map build "${robots[@]/#/$out/data/}" --range-model distance --out "$out/map-all-distance.json" \
  --trajectory-dir "$out/smoothed-all-distance" --report "$out/map-all-distance-report.json"
"$waymark" eval --map "$out/map-all-distance.json" --gt-map "$gt_map" --json "$out/map-all-distance-eval.json"
for robot in "${robots[@]}"; do
  echo "== $robot: smoothed (all robots' map, --range-model distance)"
  "$waymark" eval --est "$out/smoothed-all-distance/$robot.tum" --gt "$out/data/$robot/groundtruth/trajectory.tum" \
    --align se2 --max-dt 0.02 --rpe-delta 1 --rpe-unit m --json "$out/$robot-smoothed-distance-eval.json"
done

if [[ ${#robots[@]} -ge 5 ]]; then
  echo "== map of robots 1-3, robots 4 and 5 localized online against it"
  # The build prints the odometry calibration's correlation time it fitted (the online default).
  # --calibrate-online: the EKF's variance factor from leaving each of robots 1-3 out (printed;
  # map.json online_variance_factor, localize's default; the "unscaled" runs below disable it).
  "$waymark" map build "$out/data/robot1" "$out/data/robot2" "$out/data/robot3" --calibrate-online \
    --out "$out/map-123.json" --trajectory-dir "$out/smoothed-123"
  "$waymark" eval --map "$out/map-123.json" --gt-map "$gt_map"
  echo "== the map's landmark covariance against its error (no alignment)"
  python3 scripts/map-covariance-check.py "$out/map-123.json" "$gt_map"
  # Control: the true landmark positions (no covariance) with the map's noise model.
  python3 - "$out/map-123.json" "$gt_map" "$out/map-truth.json" <<'EOF'
import json, sys
built, truth = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
truth["range_bearing_noise"] = built["range_bearing_noise"]
truth["range_bearing_sensor"] = built["range_bearing_sensor"]
for marker in truth["markers"]:
    marker.pop("position_covariance", None)
json.dump(truth, open(sys.argv[3], "w"))
EOF
  for robot in robot4 robot5; do
    echo "== $robot: online against the map of robots 1-3"
    "$waymark" localize "$out/data/$robot" --map "$out/map-123.json" --out "$out/$robot-online.tum"
    echo "== $robot: online, the reported covariance unscaled (--variance-factor 1, the filter before)"
    "$waymark" localize "$out/data/$robot" --map "$out/map-123.json" --variance-factor 1 \
      --out "$out/$robot-online-unscaled.tum"
    "$waymark" eval --est "$out/$robot-online.tum" --gt "$out/data/$robot/groundtruth/trajectory.tum" \
      --align none --max-dt 0.02 --markers "$out/map-123.json" --gt-map "$gt_map" \
      --plot "$out/$robot-online.svg"
    echo "== $robot: online, the odometry calibration constant (--calibration-time 0, the filter before)"
    "$waymark" localize "$out/data/$robot" --map "$out/map-123.json" --calibration-time 0 \
      --out "$out/$robot-online-constant.tum"
    for mode in consider in-noise ignore; do
      echo "== $robot: online, the map's errors $mode"
      "$waymark" localize "$out/data/$robot" --map "$out/map-123.json" --map-uncertainty "$mode" \
        --out "$out/$robot-online-$mode.tum"
    done
    echo "== $robot: online against the true landmark positions (control)"
    "$waymark" localize "$out/data/$robot" --map "$out/map-truth.json" --out "$out/$robot-online-truth-map.tum"
  done
  echo "== map of robots 1-3, distance model; robots 4 and 5 online without the map's sensor prior (before)"
  "$waymark" map build "$out/data/robot1" "$out/data/robot2" "$out/data/robot3" --range-model distance \
    --out "$out/map-123-distance.json"
  for robot in robot4 robot5; do
    echo "== $robot: online against the distance-model map of robots 1-3, --sensor-prior none"
    "$waymark" localize "$out/data/$robot" --map "$out/map-123-distance.json" --sensor-prior none \
      --out "$out/$robot-online-before.tum"
  done
fi
if [[ ${#robots[@]} -ge 5 ]]; then
  # Leave-out splits: the sensor prior and the map from some robots, the others localized.
  for split in "345:1 2" "124:3 5"; do
    mapped=${split%%:*}
    located=${split#*:}
    dirs=()
    for (( i = 0; i < ${#mapped}; i++ )); do dirs+=("$out/data/robot${mapped:$i:1}"); done
    echo "== map of robots ${mapped}"
    "$waymark" map build "${dirs[@]}" --calibrate-online --out "$out/map-$mapped.json" \
      --trajectory-dir "$out/smoothed-$mapped"
    "$waymark" eval --map "$out/map-$mapped.json" --gt-map "$gt_map"
    for r in $located; do
      echo "== robot$r: online against the map of robots ${mapped}"
      "$waymark" localize "$out/data/robot$r" --map "$out/map-$mapped.json" --out "$out/robot$r-online-$mapped.tum"
      echo "== robot$r: online against the map of robots ${mapped}, the calibration constant (before)"
      "$waymark" localize "$out/data/robot$r" --map "$out/map-$mapped.json" --calibration-time 0 \
        --out "$out/robot$r-online-$mapped-constant.tum"
    done
  done
fi
