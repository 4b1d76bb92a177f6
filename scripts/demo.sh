#!/usr/bin/env bash
# The README's main job, from a clean clone on Debian 12: installs the packages Waymark needs
# (scripts/install-deps.sh), builds it (scripts/build.sh), then runs `waymark demo` on the
# dataset shipped in data/demo (a rendered survey and a separate run through the same place):
#   detect the codes in the survey's images -> learn the map (Ceres) -> detect the run's codes
#   -> localize the run against the map (loosely coupled EKF, and ours) -> evaluate against the
#   ground truth, and print the accuracy table. Reports and plots go to OUT_DIR.
# Usage: scripts/demo.sh [OUT_DIR]   (default: out/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh --target waymark
out=${1:-out/demo}
rm -rf "$out"
./build/waymark demo --data data/demo --out "$out"
